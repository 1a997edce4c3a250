#!/usr/bin/env python3
"""What ideal physics costs a dataset user: one small network trained three ways on spibench
datasets, tested on traced measurements.

    python3 examples/train_deepinv.py --size small --out out/train.json

Needs the spibench package, torch and deepinv. The network (``Net``) back-projects a
measurement through its physics' adjoint and refines the image with a small residual CNN.
It is trained

- ``ideal``: on the ideal single-pixel camera of the same patterns measured complementarily
  (deepinv physics, y = (2P − 1) D x: each DMD unit sees the object pixel that perfect imaging
  puts on it, rotated by 180° as the bench's lens images, normalised to ‖A‖ = 1), with
  Gaussian noise of the traced measurements' level;
- ``traced``: on a dataset of the paper bench's traced measurements (bench noise), with the
  traced physics (spibench.deepinv.TracedSinglePixel);
- ``drawn``: on a dataset measured through benches drawn from the paper bench's tolerance file
  (a new bench every few samples), with the nominal traced physics;

and each is tested on held-out traced measurements of the paper bench and of benches drawn
afresh. Every measurement reaches a network as a user calibrates it: the nominal bench's dark
offset y₀ removed and divided by its scale (``torch_dataset``'s measurement). The PSNR (dB,
objects in [0, 1]) of each (training, test) pair is printed and, with ``--out``, written as
JSON. ``--size tiny`` is the CI run (a few seconds of training; the test checks that the loss
falls), ``small`` the guide's figures.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time

import numpy as np
import torch
from deepinv.physics import LinearPhysics

import spibench
from spibench.deepinv import TracedSinglePixel
from spibench.noise import BenchGaussianNoise

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCHEME, RATIO = "secondary_complementary_balancing", 0.25
SIZES = {
    # grid, kernel rays, train / test samples, epochs, samples per drawn bench
    "tiny": dict(grid=16, rays=16384, train=32, test=8, epochs=4, per_bench=8),
    "small": dict(grid=32, rays=200_000, train=768, test=128, epochs=30, per_bench=32),
}


def spec_text(grid, rays, samples, seed, tolerances=None, per_bench=1):
    """A dataset spec of the paper bench (crops of the test images, SCB at 25 %)."""
    benches = (f'    benches: Tolerance(file: "{tolerances}", samples_per_bench: {per_bench}),\n'
               if tolerances else "")
    return f"""Dataset(
    bench: "{REPO}/scenes/paper_bench.ron",
    kernel: (rays: {rays}, seed: 1, grid_px: ({grid}, {grid}), field_mm: (7.88, 7.88)),
    objects: TestImages(names: ["astronaut", "coffee"], rule: RandomCrop),
    acquisition: (schemes: [SecondaryComplementaryBalancing], ratios: [{RATIO}]),
    seed: {seed},
    samples: {samples},
    shard_samples: {samples},
{benches})
"""


def make(folder, name, text):
    """The dataset of spec ``text`` in ``folder/name``, opened."""
    spec = os.path.join(folder, name + ".ron")
    with open(spec, "w") as f:
        f.write(text)
    spibench.make_dataset(spec, os.path.join(folder, name))
    return spibench.open_dataset(os.path.join(folder, name))


def ideal_physics(acq: spibench.Acquisition, dtype=torch.float32) -> LinearPhysics:
    """The ideal single-pixel camera of ``acq``'s patterns, as a complementary scheme measures
    them (each pattern minus its complement, 2P − 1, as SCB and the double arm do): unit j
    sees the object pixel perfect imaging puts on it (the object rotated by 180°),
    y = (2P − 1) D x, normalised."""
    h, w = acq.grid
    down, across = acq.units
    p = torch.from_numpy(2.0 * acq.patterns.reshape(acq.measurements, -1).astype(np.float64) - 1)
    # D: object pixel (r, c) → unit (down − 1 − ⌊r·down/h⌋, across − 1 − ⌊c·across/w⌋), area
    # weights; with fewer pixels than units each pixel covers several units.
    rows = np.minimum((np.arange(down) + 0.5) * h / down, h - 1e-9).astype(int)
    cols = np.minimum((np.arange(across) + 0.5) * w / across, w - 1e-9).astype(int)
    d = np.zeros((down * across, h * w))
    for i, r in enumerate(rows[::-1]):
        for j, c in enumerate(cols[::-1]):
            d[i * across + j, r * w + c] = 1.0
    a = p @ torch.from_numpy(d)
    a = a / torch.linalg.matrix_norm(a, ord=2)
    a = a.to(dtype)
    return LinearPhysics(A=lambda x, **k: x.reshape(x.shape[0], -1) @ a.T,
                         A_adjoint=lambda y, **k: (y @ a).reshape(y.shape[0], 1, h, w))


class Net(torch.nn.Module):
    """Back-projection through ``physics`` (gain set from the data), then a residual CNN."""

    def __init__(self, physics, channels=32):
        super().__init__()
        self.physics = physics
        self.gain = torch.nn.Parameter(torch.tensor(1.0))
        c = channels
        layers = [torch.nn.Conv2d(1, c, 3, padding=1), torch.nn.ReLU()]
        for _ in range(3):
            layers += [torch.nn.Conv2d(c, c, 3, padding=1), torch.nn.ReLU()]
        layers += [torch.nn.Conv2d(c, 1, 3, padding=1)]
        self.body = torch.nn.Sequential(*layers)

    def set_gain(self, x, y):
        """The least-squares gain of the back-projection on a batch."""
        with torch.no_grad():
            b = self.physics.A_adjoint(y)
            self.gain.copy_((b * x).sum() / (b * b).sum())

    def forward(self, y):
        b = self.gain * self.physics.A_adjoint(y)
        return b + self.body(b)


def psnr(x_hat, x):
    mse = ((x_hat.clamp(0, 1) - x) ** 2).mean(dim=(1, 2, 3))
    return float((10 * torch.log10(1.0 / mse)).mean())


def train(net, make_batch, n, epochs, seed, batch=16):
    """Adam on the MSE; ``make_batch(idx)`` gives (x, y). Returns the mean loss per epoch."""
    g = torch.Generator().manual_seed(seed)
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    net.set_gain(*make_batch(torch.arange(min(n, 64))))
    losses = []
    for _ in range(epochs):
        total = 0.0
        for idx in torch.randperm(n, generator=g).split(batch):
            x, y = make_batch(idx)
            loss = torch.nn.functional.mse_loss(net(y), x)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append(total / n)
    return losses


def tensors(ds, scale):
    """(x, y) of every sample: objects and the measurements calibrated with the nominal
    offset and scale."""
    x = torch.from_numpy(np.array(ds.array("object"), dtype=np.float32)).unsqueeze(1)
    y_v = np.array(ds.array(spibench.dataset_array_name("meas", SCHEME, RATIO)))
    return x, y_v


def run(size="small", seed=0, out=None, folder=None, epochs=None):
    """Trains and tests the three networks; returns the results (also written to ``out``).
    ``epochs`` replaces the size's number of epochs."""
    cfg = dict(SIZES[size])
    if epochs is not None:
        cfg["epochs"] = int(epochs)
    torch.manual_seed(seed)
    t0 = time.time()
    own = folder is None
    folder = folder or tempfile.mkdtemp(prefix="spibench-train-")
    tol = os.path.join(REPO, "scenes", "tolerances", "paper_bench.ron")
    g, rays, n, m = cfg["grid"], cfg["rays"], cfg["train"], cfg["test"]
    nominal = make(folder, "nominal", spec_text(g, rays, n + m, 7))
    drawn = make(folder, "drawn", spec_text(g, rays, n, 8, tol, cfg["per_bench"]))
    fresh = make(folder, "fresh", spec_text(g, rays, m, 9, tol, max(1, m // 4)))
    made_s = time.time() - t0

    acq = nominal.acquisition(SCHEME, RATIO)
    traced = TracedSinglePixel(acq, noise=None, kernel=nominal.kernel())
    scale, offset = float(traced.scale), np.asarray(acq.offset)
    cal = lambda y_v: torch.from_numpy(((y_v - offset) / scale).astype(np.float32))  # noqa: E731
    x_nom, yv_nom = tensors(nominal, scale)
    x_drawn, yv_drawn = tensors(drawn, scale)
    x_fresh, yv_fresh = tensors(fresh, scale)
    y_nom, y_drawn, y_fresh = cal(yv_nom), cal(yv_drawn), cal(yv_fresh)
    ideal = ideal_physics(acq)
    # The traced measurements' noise level in the physics' units, for the ideal training.
    noise = BenchGaussianNoise.fit(acq, scale=scale, records=8)
    sigma = float(noise.sigma(traced.A(x_nom[:n]), x_nom[:n].mean(dim=(1, 2, 3))).mean())

    gen = torch.Generator().manual_seed(seed + 1)

    def ideal_batch(idx):
        x = x_nom[idx]
        y = ideal.A(x)
        return x, y + sigma * torch.randn(y.shape, generator=gen)

    setups = {
        "ideal": (ideal, ideal_batch),
        "traced": (traced, lambda idx: (x_nom[idx], y_nom[idx])),
        "drawn": (traced, lambda idx: (x_drawn[idx], y_drawn[idx])),
    }
    results = {"size": size, "seed": seed, "grid": g, "scheme": SCHEME, "ratio": RATIO, "train": n,
               "test": m, "epochs": cfg["epochs"], "noise_sigma": sigma,
               "datasets_s": round(made_s, 1), "psnr_db": {}, "losses": {}}
    for name, (phys, batch) in setups.items():
        torch.manual_seed(seed)
        net = Net(phys)
        t1 = time.time()
        results["losses"][name] = train(net, batch, n, cfg["epochs"], seed)
        with torch.no_grad():
            results["psnr_db"][name] = {
                "paper_bench": psnr(net(y_nom[n:]), x_nom[n:]),
                "drawn_benches": psnr(net(y_fresh), x_fresh),
            }
        results.setdefault("train_s", {})[name] = round(time.time() - t1, 1)
    with torch.no_grad():
        bp = Net(traced)
        bp.set_gain(x_nom[:64], y_nom[:64])
        results["psnr_db"]["back_projection"] = {
            "paper_bench": psnr(bp.gain * traced.A_adjoint(y_nom[n:]), x_nom[n:]),
            "drawn_benches": psnr(bp.gain * traced.A_adjoint(y_fresh), x_fresh)}
    results["total_s"] = round(time.time() - t0, 1)
    if own:
        import shutil

        shutil.rmtree(folder, ignore_errors=True)
    if out:
        os.makedirs(os.path.dirname(os.path.abspath(out)), exist_ok=True)
        with open(out, "w") as f:
            json.dump(results, f, indent=1)
    return results


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", choices=sorted(SIZES), default="small")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--epochs", type=int, help="epochs of each training (default: the size's)")
    ap.add_argument("--out", help="write the results as JSON here")
    args = ap.parse_args()
    if args.epochs is not None and args.epochs < 1:
        ap.error(f"--epochs: at least 1, got {args.epochs}")
    r = run(args.size, args.seed, args.out, epochs=args.epochs)
    print(f"{r['size']}: {r['train']} training and {r['test']} test samples of {r['grid']}×"
          f"{r['grid']}, {SCHEME} at {RATIO:.0%}, {r['epochs']} epochs ({r['total_s']} s)")
    print(f"{'trained on':<16}{'paper bench':>14}{'drawn benches':>16}   (PSNR, dB)")
    for name, v in r["psnr_db"].items():
        print(f"{name:<16}{v['paper_bench']:>14.2f}{v['drawn_benches']:>16.2f}")


if __name__ == "__main__":
    main()
