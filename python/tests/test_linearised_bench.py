"""The first-order expansion of the traced acquisition in bench variables
(spibench.deepinv.LinearisedBench) and its generator (skipped without torch and deepinv)."""

from __future__ import annotations

import numpy as np
import pytest

import spibench
from conftest import FIELD_MM, GRID, KERNEL_RAYS

torch = pytest.importorskip("torch")
pytest.importorskip("deepinv")

from spibench.deepinv import DeviationGenerator, LinearisedBench  # noqa: E402

SCB = "secondary_complementary_balancing"
# The − diode's flat responsivity scale multiplies its photocurrent after the trace
# (src/pipeline/operator.rs, Coefficients::new): SCB's A and y₀ are affine in it, so the
# central difference is its derivative exactly. The chart's decentre moves the traced light.
SCALE = "electronics.detector.responsivity_scale_minus"
CHART = "chart.decenter_mm.x"
SEED = 3


@pytest.fixture(scope="module")
def paper():
    return spibench.Bench.paper()


@pytest.fixture(scope="module")
def lin(paper):
    return LinearisedBench(paper, {SCALE: 0.02, CHART: 0.1}, GRID, FIELD_MM, KERNEL_RAYS,
                           seed=SEED, scheme=SCB, ratio=0.25, dtype=torch.float64)


def traced(bench):
    """The acquisition of ``bench`` traced with the expansion's rays and seed, and its A."""
    acq = spibench.Acquisition(bench.kernel(GRID, FIELD_MM, KERNEL_RAYS, seed=SEED), SCB, 0.25)
    return acq, acq.matrix()


def objects(n=3):
    return torch.from_numpy(np.random.default_rng(5).random((n, 1) + GRID))


def test_no_deviation_is_the_nominal_bench(paper, lin):
    acq, a = traced(paper)
    x = objects()
    want = x.reshape(3, -1).numpy() @ a.T / float(lin.scale)
    got = lin.A(x, deviation=torch.zeros(2)).numpy()
    assert np.allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    assert float(lin.scale) == pytest.approx(acq.operator_norm(), rel=1e-12)
    assert np.allclose(lin.offsets(1).numpy()[0], acq.offset, rtol=1e-12, atol=0)


def test_exact_where_the_acquisition_is_linear_in_the_variable(paper, lin):
    """δ on the responsivity scale: the expansion is the bench traced there, to rounding."""
    x = objects()
    for d in (0.015, -0.03):
        acq, a = traced(paper.set({SCALE: paper.get(SCALE) + d}))
        want = x.reshape(3, -1).numpy() @ a.T / float(lin.scale)
        got = lin.A(x, deviation=[d, 0.0]).numpy()
        assert np.allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max()), d
        off = lin.offsets(1).numpy()[0]
        assert np.allclose(off, acq.offset, rtol=0, atol=1e-10 * np.abs(acq.offset).max()), d


def test_per_sample_deviations_adjoint_and_autograd(lin):
    x = objects(4)
    dev = torch.tensor([[0.01, 0.0], [0.0, 0.05], [-0.02, -0.08], [0.0, 0.0]], dtype=torch.float64)
    y = lin.A(x, deviation=dev)
    # Each sample through its own deviation, as the physics gives it alone.
    for b in range(4):
        alone = lin.A(x[b:b + 1], deviation=dev[b])
        assert float((y[b] - alone[0]).abs().max()) < 1e-13 * float(y.abs().max())
    lin.update_parameters(deviation=dev)
    v = torch.randn(y.shape, dtype=torch.float64, generator=torch.Generator().manual_seed(1))
    lhs, rhs = float((y * v).sum()), float((lin.A_adjoint(v) * x).sum())
    assert abs(lhs - rhs) < 1e-12 * abs(lhs)
    xg = x.clone().requires_grad_(True)
    (lin.A(xg) ** 2).sum().backward()
    assert torch.allclose(xg.grad, 2 * lin.A_adjoint(lin.A(x)), rtol=1e-12, atol=0)
    # A changes with the chart's decentre (the traced light moves).
    moved = lin.A(x[:1], deviation=[0.0, 0.1])
    assert not torch.allclose(moved, lin.A(x[:1], deviation=[0.0, 0.0]))


def test_generator_draws_within_the_ranges_reproducibly():
    g = DeviationGenerator(ranges=[0.02, 0.5], seed=4, dtype=torch.float64)
    d = g.step(1000)["deviation"]
    assert d.shape == (1000, 2)
    assert float(d[:, 0].abs().max()) <= 0.02 and float(d[:, 1].abs().max()) <= 0.5
    # Uniform on ±w: variance w²/3; its estimate over 1000 draws has relative SE √(4/5/1000)
    # ≈ 2.8 %: 5 SE.
    assert float(d[:, 1].var()) == pytest.approx(0.25 / 3, rel=0.14)
    again = DeviationGenerator(ranges=[0.02, 0.5], seed=4, dtype=torch.float64).step(1000)
    assert torch.equal(d, again["deviation"])
    n = DeviationGenerator(sigmas=[0.1], seed=1, dtype=torch.float64).step(2000)["deviation"]
    # Normal: the variance's relative SE √(2/2000) ≈ 3.2 %: 5 SE.
    assert float(n.var()) == pytest.approx(0.01, rel=0.16)


def test_refusals(paper):
    with pytest.raises(spibench.InputError, match="not a variable"):
        LinearisedBench(paper, {"nothing.here": 0.1}, GRID, FIELD_MM, KERNEL_RAYS)
    with pytest.raises(spibench.InputError, match="positive"):
        LinearisedBench(paper, {SCALE: 0.0}, GRID, FIELD_MM, KERNEL_RAYS)
    with pytest.raises(spibench.InputError, match="noise_model"):
        LinearisedBench(paper, {SCALE: 0.01}, GRID, FIELD_MM, KERNEL_RAYS, noise_model="bench")
    with pytest.raises(spibench.InputError, match="ranges"):
        DeviationGenerator()
    with pytest.raises(spibench.InputError, match="sigmas"):
        DeviationGenerator(sigmas=[-1.0])


def test_patterns_are_held_packed_with_padding_bits(paper, monkeypatch):
    """10 × 10 DMD units: the buffer is numpy.packbits of P, 13 bytes a row (4 padding bits);
    A and Aᵀ equal the expansion with P unpacked, in one block and in blocks of 2 rows; the
    buffer survives a state_dict round trip."""
    import spibench.nn as nn

    small = paper.set({"dmd.pattern.units_across": 10, "dmd.pattern.units_down": 10,
                       "dmd.pattern.mirrors_per_unit": 57})
    lin = LinearisedBench(small, {SCALE: 0.02}, (10, 10), FIELD_MM, 4096, seed=SEED, scheme=SCB,
                          ratio=0.25, dtype=torch.float64)
    acq = lin.acquisition
    assert lin.patterns.dtype == torch.uint8 and tuple(lin.patterns.shape) == (25, 13)
    assert np.array_equal(lin.patterns.numpy(), np.packbits(
        acq.patterns.reshape(acq.measurements, -1), axis=1))
    x = torch.from_numpy(np.random.default_rng(6).random((3, 1, 10, 10)))
    y = torch.from_numpy(np.random.default_rng(7).standard_normal((3, acq.measurements)))
    d = torch.tensor([[0.01], [-0.02], [0.0]], dtype=torch.float64)
    p = torch.from_numpy(acq.patterns.reshape(acq.measurements, -1).astype(np.float64))
    xf = x.reshape(3, -1)
    u = xf @ lin.g0.T + torch.einsum("bv,vup,bp->bu", d, lin.dg, xf)
    want = (u @ p.T + (xf * (lin.r0 + d @ lin.dr)).sum(dim=1, keepdim=True)) / lin.scale
    v = y @ p
    back = v @ lin.g0 + torch.einsum("bv,vup,bu->bp", d, lin.dg, v)
    back = (back + y.sum(dim=1, keepdim=True) * (lin.r0 + d @ lin.dr)) / lin.scale
    for block in (nn._BLOCK_ENTRIES, 2 * 100 + 7):
        monkeypatch.setattr(nn, "_BLOCK_ENTRIES", block)
        got = lin.A(x, deviation=d)
        assert float((got - want).abs().max()) <= 1e-13 * float(want.abs().max())
        adj = lin.A_adjoint(y, deviation=d).reshape(3, -1)
        assert float((adj - back).abs().max()) <= 1e-13 * float(back.abs().max())
    state = lin.state_dict()
    assert state["patterns"].dtype == torch.uint8 and tuple(state["patterns"].shape) == (25, 13)
    lin32 = LinearisedBench(small, {SCALE: 0.02}, (10, 10), FIELD_MM, 4096, seed=SEED,
                            scheme=SCB, ratio=0.25)
    assert torch.equal(lin32.patterns, lin.patterns)
    assert lin32.A(x.float(), deviation=d.float()).dtype == torch.float32
