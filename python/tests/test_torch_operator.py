"""The torch-native operator ``spibench.nn.TracedLinear`` (skipped without torch)."""

from __future__ import annotations

import io

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import spibench  # noqa: E402
import spibench.nn as nn  # noqa: E402
from spibench.nn import TracedLinear, _folded  # noqa: E402

SCHEMES = ["secondary_complementary_balancing", "double_arm", "double_arm_calibrated",
           "traditional", "single_arm_complementary"]
FORMS = [("csr", True), ("dense", True), ("matrix", False)]


def operator(kernel, scheme, form, with_kernel, dtype):
    """The acquisition of ``scheme`` at 25 % and its torch operator in ``form``."""
    acq = spibench.Acquisition(kernel, scheme, 0.25)
    fmt = "dense" if form == "dense" else "csr"
    return acq, TracedLinear(acq, kernel if with_kernel else None, dtype=dtype, kernel_format=fmt)


def rel(a, b) -> float:
    """‖a − b‖ / ‖b‖."""
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(np.asarray(b)))


def rounding_scales(kernel, acq, x, y):
    """The magnitudes float32 rounds at, per measurement and per pixel: P(|G| x) + |r|·x for
    A x (x ≥ 0) and |G|ᵀ(P|y|) + |r|·Σ|y| for Aᵀ y (the terms before they cancel)."""
    g, r = _folded(acq, kernel)
    g = abs(g)
    p = acq.patterns.reshape(acq.measurements, -1).astype(np.float64)
    xf = x.reshape(len(x), -1)
    fwd = (p @ (g @ xf.T)).T + (xf @ abs(r))[:, None]
    adj = (g.T @ (p.T @ abs(y).T)).T + abs(y).sum(axis=1)[:, None] * abs(r)
    return fwd, adj.reshape((len(y),) + acq.grid)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("form,with_kernel", FORMS)
def test_equals_the_library_operator(kernel, scheme, form, with_kernel):
    acq, op = operator(kernel, scheme, form, with_kernel, torch.float64)
    rng = np.random.default_rng(1)
    x = rng.random((3,) + acq.grid)
    y = rng.standard_normal((3, acq.measurements))
    assert rel(op(torch.from_numpy(x)), acq.apply(x)) < 1e-12
    assert rel(op.adjoint(torch.from_numpy(y)), acq.adjoint(y)) < 1e-12
    assert np.array_equal(op.offset.numpy(), acq.offset)
    # float32: within float32 rounding of the terms (which cancel in the balanced schemes).
    x, y = np.float32(x).astype(np.float64), np.float32(y).astype(np.float64)
    fwd, adj = rounding_scales(kernel, acq, x, y)
    op32 = op.float()
    assert op32.offset.dtype == torch.float32
    got = op32(torch.from_numpy(x).float())
    assert got.dtype == torch.float32
    eps = float(np.finfo(np.float32).eps)
    assert rel(got.double(), acq.apply(x)) < 1e-3
    assert np.linalg.norm(got.double().numpy() - acq.apply(x)) < 8 * eps * np.linalg.norm(fwd)
    back = op32.adjoint(torch.from_numpy(y).float()).double().numpy()
    assert np.linalg.norm(back - acq.adjoint(y)) < 8 * eps * np.linalg.norm(adj)


@pytest.mark.parametrize("dtype,tol", [(torch.float32, 1e-5), (torch.float64, 1e-12)])
@pytest.mark.parametrize("form,with_kernel", FORMS)
def test_adjointness(kernel, dtype, tol, form, with_kernel):
    _, op = operator(kernel, "double_arm", form, with_kernel, dtype)
    g = torch.Generator().manual_seed(0)
    x = torch.rand((5,) + op.grid, generator=g, dtype=dtype)
    y = torch.randn(5, op.measurements, generator=g, dtype=dtype)
    lhs = (op(x) * y).sum(dim=-1)
    rhs = (x * op.adjoint(y)).sum(dim=(-2, -1))
    scale = (op(x).abs() * y.abs()).sum(dim=-1)
    assert float(((lhs - rhs).abs() / scale).max()) < tol


def test_shapes_follow_spyrit(kernel):
    acq, op = operator(kernel, "secondary_complementary_balancing", "csr", True, torch.float64)
    x = torch.rand((2, 3) + acq.grid, dtype=torch.float64)
    y = op(x)
    assert y.shape == (2, 3, acq.measurements)
    assert op.adjoint(y).shape == x.shape
    assert op(x[0, 0]).shape == (acq.measurements,)
    with pytest.raises(spibench.InputError, match="shape"):
        op(torch.rand(2, 5, 5, dtype=torch.float64))
    with pytest.raises(spibench.InputError, match="float32"):
        op(x.float())


def test_autograd_goes_through_the_adjoint(kernel):
    acq, op = operator(kernel, "double_arm", "csr", True, torch.float64)
    x = torch.rand((2,) + acq.grid, dtype=torch.float64, requires_grad=True)
    y = torch.randn(2, acq.measurements, dtype=torch.float64, requires_grad=True)
    (op(x) * y.detach()).sum().backward()
    assert torch.allclose(x.grad, op.adjoint(y.detach()), rtol=1e-12, atol=0)
    (op.adjoint(y) * x.detach()).sum().backward()
    assert torch.allclose(y.grad, op(x.detach()), rtol=1e-12, atol=0)
    assert torch.autograd.gradcheck(lambda v: op(v), (x[:1].detach().requires_grad_(),),
                                    fast_mode=True)


def test_buffers_move_and_load(kernel):
    acq, op = operator(kernel, "double_arm", "csr", True, torch.float32)
    names = {n for n, _ in op.named_buffers()}
    assert {"offset", "patterns", "r", "g_values", "gt_values"} <= names
    op.double()
    assert all(b.dtype == torch.float64 for n, b in op.named_buffers() if b.is_floating_point())
    assert op.patterns.dtype == torch.uint8
    buf = io.BytesIO()
    torch.save(op.state_dict(), buf)
    other = TracedLinear(acq, kernel, dtype=torch.float64)
    with torch.no_grad():
        other.r.zero_()
    buf.seek(0)
    other.load_state_dict(torch.load(buf))
    x = torch.rand(acq.grid, dtype=torch.float64)
    assert torch.equal(other(x), op(x))
    op.to("meta")
    assert all(b.device.type == "meta" for b in op.buffers())


def unpacked_reference(acq, kernel, x, y):
    """A x and Aᵀ y in float64 with P as a plain 0/1 matrix (the unpacked layout)."""
    g, r = _folded(acq, kernel)
    p = acq.patterns.reshape(acq.measurements, -1).astype(np.float64)
    xf = x.reshape(len(x), -1)
    fwd = (p @ (g @ xf.T)).T + (xf @ r)[:, None]
    adj = (g.T @ (p.T @ y.T)).T + y.sum(axis=1)[:, None] * r
    return fwd, adj.reshape((len(y),) + acq.grid)


@pytest.mark.parametrize("side,mirrors", [(12, 48), (10, 57)])
@pytest.mark.parametrize("form", ["csr", "dense"])
def test_patterns_are_held_packed(paper, side, mirrors, form, monkeypatch):
    """The buffer is numpy.packbits of P (rows × ⌈units/8⌉ bytes): 12 × 12 units pack into
    whole bytes, 10 × 10 leave 4 padding bits a row; A and Aᵀ equal the unpacked reference, in
    one block and in blocks of a few rows."""
    bench = paper.set({"dmd.pattern.units_across": side, "dmd.pattern.units_down": side,
                       "dmd.pattern.mirrors_per_unit": mirrors})
    kern = bench.kernel(grid=(side, side), field_mm=7.88, rays=4096, seed=3)
    acq = spibench.Acquisition(kern, "secondary_complementary_balancing", 0.25)
    units = int(np.prod(acq.units))
    assert units == side * side
    rng = np.random.default_rng(4)
    x = rng.random((3,) + acq.grid)
    y = rng.standard_normal((3, acq.measurements))
    fwd, adj = unpacked_reference(acq, kern, x, y)
    for block in (nn._BLOCK_ENTRIES, 3 * units + 1):
        # 3 * units + 1: blocks of 3 rows, the last one shorter (M = 36 or 25).
        monkeypatch.setattr(nn, "_BLOCK_ENTRIES", block)
        op = TracedLinear(acq, kern, dtype=torch.float64, kernel_format=form)
        assert op.patterns.dtype == torch.uint8
        assert tuple(op.patterns.shape) == (acq.measurements, -(-units // 8))
        assert op.patterns.numel() == acq.measurements * -(-units // 8)
        assert np.array_equal(op.patterns.numpy(), acq.patterns_packed)
        assert np.array_equal(op.patterns.numpy(), np.packbits(
            acq.patterns.reshape(acq.measurements, -1), axis=1))
        unpacked = nn._unpack(op.patterns, units, torch.float64).numpy()
        assert np.array_equal(unpacked, acq.patterns.reshape(acq.measurements, -1))
        assert rel(op(torch.from_numpy(x)), fwd) < 1e-13
        assert rel(op.adjoint(torch.from_numpy(y)), adj) < 1e-13
        assert rel(op(torch.from_numpy(x)), acq.apply(x)) < 1e-12
        assert rel(op.adjoint(torch.from_numpy(y)), acq.adjoint(y)) < 1e-12
        op32 = TracedLinear(acq, kern, kernel_format=form)
        assert torch.equal(op32.patterns, op.patterns)
        assert op32(torch.from_numpy(x).float()).dtype == torch.float32
        assert rel(op32(torch.from_numpy(x).float()).double(), fwd) < 1e-3


@pytest.mark.skipif(not torch.cuda.is_available(), reason="no CUDA device")
def test_on_cuda(kernel):
    acq, op = operator(kernel, "secondary_complementary_balancing", "csr", True, torch.float64)
    op.to("cuda")
    assert all(b.device.type == "cuda" for b in op.buffers())
    x = np.random.default_rng(2).random((4,) + acq.grid)
    y = op(torch.from_numpy(x).cuda())
    assert y.device.type == "cuda"
    assert rel(y.cpu(), acq.apply(x)) < 1e-12
    assert op.adjoint(y).device.type == "cuda"


def test_refuses_a_foreign_kernel(kernel, paper):
    other = paper.kernel(grid=kernel.grid, field_mm=7.88, rays=4096, seed=11)
    acq = spibench.Acquisition(other, "double_arm", 0.25)
    with pytest.raises(spibench.InputError, match="kernel"):
        TracedLinear(acq, kernel)
