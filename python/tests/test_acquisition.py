"""The acquisition operator: forward equals `spibench dataset` bit for bit (noise off and on),
the linear part and its exact adjoint for every scheme, the offset."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

import spibench
from conftest import DATASET_SCHEMES, make_spec, paper_text, spibench_binary

KEYS = {
    "SecondaryComplementaryBalancing": "secondary_complementary_balancing",
    "DoubleArm": "double_arm",
    "DoubleArmCalibrated": "double_arm_calibrated",
    "Traditional": "traditional",
}


def test_forward_equals_the_dataset_bit_for_bit(dataset):
    ds, noise = dataset
    objects = np.asarray(ds.array("object"))
    assert objects.shape == (3, 12, 12)
    for scheme in DATASET_SCHEMES:
        for ratio in (0.05, 0.1):
            key = KEYS[scheme]
            acq = ds.acquisition(key, ratio)
            assert acq.noise_default == noise
            y = acq.forward(objects, noise=noise, seed=ds.seed)
            want = np.asarray(ds.array(spibench.dataset_array_name("meas", key, ratio)))
            assert y.shape == want.shape
            assert np.array_equal(y, want), (scheme, ratio)
            # One sample alone, with its own record seed.
            s = 2
            y2 = acq.forward(objects[s], noise=noise, seed=[spibench.dataset_noise_seed(ds.seed, s)])
            assert np.array_equal(y2[0] if y2.ndim == 2 else y2, want[s])
    # With noise on, another seed gives other measurements.
    if noise:
        acq = ds.acquisition("double_arm", 0.1)
        assert not np.array_equal(acq.forward(objects, noise=True, seed=ds.seed + 1),
                                  np.asarray(ds.array(spibench.dataset_array_name("meas", "double_arm", 0.1))))


def test_forward_is_the_same_on_one_thread(dataset):
    ds, noise = dataset
    objects = np.asarray(ds.array("object"))
    acq = ds.acquisition("secondary_complementary_balancing", 0.1)
    a = acq.forward(objects, noise=noise, seed=ds.seed, threads=1)
    b = acq.forward(objects, noise=noise, seed=ds.seed, threads=2)
    assert np.array_equal(a, b)


def test_forward_equals_the_command_line_dataset(tmp_path):
    """The same spec through the `spibench dataset` program."""
    exe = spibench_binary()
    if exe is None:
        pytest.skip("the spibench program is not built (cargo build; or set SPIBENCH_BIN)")
    bench = tmp_path / "bench.ron"
    bench.write_text(paper_text(noise=True))
    spec = make_spec(tmp_path, bench, ["SecondaryComplementaryBalancing", "DoubleArm"], [0.05],
                     samples=2, shard=2)
    out = tmp_path / "cli"
    subprocess.run([exe, "dataset", str(spec), "--out", str(out)], check=True,
                   capture_output=True)
    ds = spibench.open_dataset(out)
    objects = np.asarray(ds.array("object"))
    for key in ("secondary_complementary_balancing", "double_arm"):
        y = ds.acquisition(key, 0.05).forward(objects, noise=True, seed=ds.seed)
        assert np.array_equal(y, np.asarray(ds.array(spibench.dataset_array_name("meas", key, 0.05))))


@pytest.mark.parametrize("scheme", spibench.SCHEMES)
def test_adjointness(kernel, scheme):
    acq = spibench.Acquisition(kernel, scheme, 0.1)
    rng = np.random.default_rng(5)
    x = rng.random((4,) + acq.grid)
    y = rng.standard_normal((4, acq.measurements))
    ax = acq.apply(x)
    aty = acq.adjoint(y)
    lhs = np.sum(ax * y, axis=1)
    rhs = np.sum(x * aty, axis=(1, 2))
    # Relative to the Cauchy–Schwarz bound |<Ax, y>| <= ||Ax|| ||y|| (random y makes <Ax, y>
    # itself a sum of cancelling terms).
    scale = np.linalg.norm(ax, axis=1) * np.linalg.norm(y, axis=1)
    assert np.all(np.abs(lhs - rhs) <= 1e-12 * scale), (lhs - rhs) / scale
    # The dense matrix is the same operator.
    a = acq.matrix()
    assert a.shape == acq.shape
    assert np.allclose(a @ x[0].ravel(), ax[0], rtol=0, atol=1e-12 * np.max(np.abs(ax[0])))


@pytest.mark.parametrize("scheme", [s for s in spibench.SCHEMES if s != "double_arm_calibrated"])
def test_linear_part_and_offset_give_the_noise_free_forward(kernel, scheme):
    acq = spibench.Acquisition(kernel, scheme, 0.1)
    x = np.random.default_rng(2).random((3,) + acq.grid)
    # A x + y₀ is the measurement through the kernel's linear part, exactly.
    y = acq.forward(x, noise=False, linear=True)
    model = acq.apply(x) + acq.offset
    assert np.max(np.abs(model - y)) <= 1e-9 * np.max(np.abs(y))
    # The full measurement adds the light that meets the chart more than once (weighted by
    # every pixel it met, the linear part by the first only). Bound from the physics: y_i is
    # ka·a_i + kb·b_i + ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ + const (pipeline::operator), where
    # a_i, S₊, c₊ are sums of diode +'s T entries over disjoint sets of (state, unit) plus its
    # pattern-independent light (b_i, S₋, c₋ the same for diode −), and each path's weight
    # changes by at most its current for objects in [0, 1]. So every measurement moves by at
    # most (Σ |k|)·M, M the clear chart's current on paths that met it more than once.
    full = acq.forward(x, noise=False)
    bound = np.sum(np.abs(acq.coefficients)) * kernel.multi_crossing_current_a
    moved = np.max(np.abs(full - y))
    assert 0 < moved <= bound, (moved, bound)


def test_calibrated_scheme_matches_on_the_clear_object(kernel):
    acq = spibench.Acquisition(kernel, "double_arm_calibrated", 0.1)
    ones = np.ones(acq.grid)
    y = acq.forward(ones, noise=False)
    assert np.allclose(acq.apply(ones) + acq.offset, y, rtol=0, atol=1e-9 * np.max(np.abs(y)))


def test_patterns(kernel):
    acq = spibench.Acquisition(kernel, "double_arm", 0.05)
    p = acq.patterns
    assert p.shape == (acq.measurements,) + acq.units
    assert set(np.unique(p)) <= {0, 1}
    packed = acq.patterns_packed
    assert np.array_equal(np.unpackbits(packed, axis=1)[:, : p[0].size], p.reshape(len(p), -1))
    # The traditional scheme reads P x: its linear part is a gain times the pattern's light.
    t = spibench.Acquisition(kernel, "traditional", 0.05)
    assert np.array_equal(t.patterns, p)


def test_public_constructors_take_no_private_keyword():
    import inspect

    for cls in (spibench.Acquisition, spibench.Bench, spibench.OpenDataset):
        private = [p for p in inspect.signature(cls).parameters if p.startswith("_")]
        assert not private, (cls, private)
