"""Benchmarks of the Python package (figures for the closing note; not a test).

1. Forward (A) and adjoint (Aᵀ) of a batch of 64 objects of 96 × 96 through a traced kernel
   of the paper bench at 25 % (SCB): the Python call against the same library work timed
   inside Rust (`Acquisition.time_rust`): the Python layer's overhead.
2. The simulated measurement (`forward`, noise on) of the same batch.
3. deepinv's SinglePixelCamera at the same size on CPU (when torch and deepinv import), fast
   (Hadamard) and dense random, float32 and float64.
4. The torch operator ``spibench.nn.TracedLinear`` (kernel as CSR and as a dense matrix,
   float32 and float64) and the deepinv physics ``TracedSinglePixel`` around it: forward +
   adjoint of the same batch, with torch on ``--threads`` threads, in the same run as 1 and 3.

Usage: python bench_operator.py [--out results.json] [--rays N] [--repeats R] [--threads T]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time

import numpy as np

import spibench


def best_of(f, repeats):
    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t)
    return best


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=None)
    ap.add_argument("--rays", type=int, default=1 << 20)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--batch", type=int, default=64)
    ap.add_argument("--threads", type=int, default=None)
    a = ap.parse_args()
    res = {"machine": platform.machine(), "python": platform.python_version(),
           "cpus": os.cpu_count(), "spibench": spibench.__version__, "threads": a.threads}
    grid = (96, 96)
    t0 = time.perf_counter()
    kernel = spibench.Bench.paper().kernel(grid=grid, field_mm=7.88, rays=a.rays, seed=1,
                                           threads=a.threads)
    res["kernel_rays"] = a.rays
    res["kernel_trace_s"] = time.perf_counter() - t0
    res["kernel_entries_g"] = int(kernel.g_a[0].nnz)
    acq = spibench.Acquisition(kernel, "secondary_complementary_balancing", 0.25)
    res["measurements"] = acq.measurements
    res["units"] = acq.units
    rng = np.random.default_rng(0)
    x = rng.random((a.batch,) + grid)
    y = rng.standard_normal((a.batch, acq.measurements))
    xf = np.ascontiguousarray(x.reshape(a.batch, -1))
    yf = np.ascontiguousarray(y)
    r = a.repeats
    res["apply_python_s"] = best_of(lambda: acq.apply(x, threads=a.threads), r)
    res["apply_rust_s"] = acq._a.time_rust(xf, False, r, a.threads)
    res["adjoint_python_s"] = best_of(lambda: acq.adjoint(y, threads=a.threads), r)
    res["adjoint_rust_s"] = acq._a.time_rust(yf, True, r, a.threads)
    for k in ("apply", "adjoint"):
        res[f"{k}_overhead"] = res[f"{k}_python_s"] / res[f"{k}_rust_s"] - 1.0
    res["forward_noisy_s"] = best_of(lambda: acq.forward(x, noise=True, seed=1,
                                                         threads=a.threads), max(1, r // 3))
    try:
        import torch
        from deepinv.physics import SinglePixelCamera

        res["torch"] = torch.__version__
        if a.threads:
            torch.set_num_threads(a.threads)
        res["torch_threads"] = torch.get_num_threads()
        for fast in (True, False):
            for dtype in (torch.float32, torch.float64):
                try:
                    spc = SinglePixelCamera(m=acq.measurements, img_size=(1,) + grid,
                                            fast=fast, dtype=dtype)
                except ValueError as e:
                    # The fast (FWHT) camera needs power-of-two sides; 96 × 96 is not.
                    res[f"deepinv_spc_{'fast' if fast else 'dense'}"] = f"not run: {e}"
                    continue
                xt = torch.from_numpy(x[:, None]).to(dtype)
                yt = spc.A(xt)
                name = f"deepinv_spc_{'fast' if fast else 'dense'}_{str(dtype)[6:]}"
                with torch.no_grad():
                    res[name + "_A_s"] = best_of(lambda: spc.A(xt), r)
                    res[name + "_At_s"] = best_of(lambda: spc.A_adjoint(yt), r)
        from spibench.deepinv import TracedSinglePixel
        from spibench.nn import TracedLinear

        both = lambda f, g: best_of(lambda: (f(), g()), r)  # noqa: E731
        res["numpy_A_At_s"] = both(lambda: acq.apply(x, threads=a.threads),
                                   lambda: acq.adjoint(y, threads=a.threads))
        for fmt in ("csr", "dense"):
            for dtype in (torch.float32, torch.float64):
                t0 = time.perf_counter()
                op = TracedLinear(acq, kernel, dtype=dtype, kernel_format=fmt)
                name = f"torch_{fmt}_{str(dtype)[6:]}"
                res[name + "_build_s"] = time.perf_counter() - t0
                res[name + "_patterns_bytes"] = op.patterns.numel() * op.patterns.element_size()
                xt = torch.from_numpy(x).to(dtype)
                yt = torch.from_numpy(y).to(dtype)
                with torch.no_grad():
                    res[name + "_A_s"] = best_of(lambda: op(xt), r)
                    res[name + "_At_s"] = best_of(lambda: op.adjoint(yt), r)
                    res[name + "_A_At_s"] = both(lambda: op(xt), lambda: op.adjoint(yt))
                    ref = acq.apply(x, threads=a.threads)
                    res[name + "_rel_err_vs_rust"] = float(
                        np.linalg.norm(op(xt).double().numpy() - ref) / np.linalg.norm(ref))
        phys = TracedSinglePixel(acq, noise=None, kernel=kernel)
        xt = torch.from_numpy(x[:, None]).float()
        yt = torch.from_numpy(y).float()
        with torch.no_grad():
            res["traced_deepinv_A_s"] = best_of(lambda: phys.A(xt), r)
            res["traced_deepinv_At_s"] = best_of(lambda: phys.A_adjoint(yt), r)
            res["traced_deepinv_A_At_s"] = both(lambda: phys.A(xt), lambda: phys.A_adjoint(yt))
        spc = SinglePixelCamera(m=acq.measurements, img_size=(1,) + grid, fast=False,
                                dtype=torch.float32)
        ys = spc.A(xt)
        with torch.no_grad():
            res["deepinv_spc_dense_float32_A_At_s"] = both(lambda: spc.A(xt),
                                                           lambda: spc.A_adjoint(ys))
        phys64 = TracedSinglePixel(acq, noise=None, kernel=kernel, dtype=torch.float64)
        res["traced_deepinv_adjointness_float64"] = float(phys64.adjointness_test(
            img_size=(1,) + grid, dtype=torch.float64))
        res["traced_deepinv_adjointness_float32"] = float(phys.adjointness_test(
            img_size=(1,) + grid, dtype=torch.float32))
    except ImportError as e:
        res["deepinv"] = f"not run: {e}"
    text = json.dumps(res, indent=2)
    print(text)
    if a.out:
        with open(a.out, "w") as f:
            f.write(text + "\n")


if __name__ == "__main__":
    main()
