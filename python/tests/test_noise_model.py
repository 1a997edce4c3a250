"""The bench's noise as a deepinv noise model, against the library's full simulation (skipped
without torch and deepinv)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("deepinv")

import spibench  # noqa: E402
from spibench.deepinv import TracedSinglePixel  # noqa: E402
from spibench.noise import BenchGaussianNoise, measured_moments  # noqa: E402

#: The reduction's stated accuracy (spibench/noise.py): σ within 10 % of the simulation's.
SIGMA_ACCURACY = 0.10
RECORDS = 48


def held_out_objects(grid):
    """Objects unlike the calibration set: a uniform 0.25, a texture in [0.1, 0.9] and a
    two-level block object."""
    h, w = grid
    rng = np.random.default_rng(11)
    blocks = np.zeros((h, w))
    blocks[: h // 2, : w // 3] = 0.9
    blocks[h // 3:, w // 2:] = 0.3
    return np.stack([np.full((h, w), 0.25), 0.1 + 0.8 * rng.random((h, w)), blocks])


@pytest.mark.parametrize("scheme", ["secondary_complementary_balancing", "double_arm", "traditional"])
def test_gaussian_model_matches_the_simulation_per_measurement(kernel, scheme):
    """Held-out objects recorded RECORDS times by the library: the standardised residuals
    z = (y − v)/σ_model have mean 0 and mean square 1 within the stated accuracy, each with 5
    standard errors computed over the independent records (the drift correlates the
    measurements of one record)."""
    acq = spibench.Acquisition(kernel, scheme, 0.25)
    model = BenchGaussianNoise.fit(acq, records=32, dtype=torch.float64)
    obj = held_out_objects(acq.grid)
    v = np.asarray(acq.forward(obj, noise=False))
    light = torch.from_numpy(obj.reshape(len(obj), -1).mean(1))
    sigma = np.sqrt(model.variance_v(torch.from_numpy(v), light).numpy())
    for j in range(len(obj)):
        y = np.asarray(acq.forward(np.repeat(obj[j][None], RECORDS, 0), noise=True,
                                   seed=[5000 + j * RECORDS + r for r in range(RECORDS)]))
        z = (y - v[j]) / sigma[j]
        per_record_mean = z.mean(1)
        per_record_ms = (z * z).mean(1)
        se_mean = per_record_mean.std(ddof=1) / np.sqrt(RECORDS)
        assert abs(per_record_mean.mean()) < 5 * se_mean + 0.05, (scheme, j, per_record_mean.mean())
        ms, se_ms = per_record_ms.mean(), per_record_ms.std(ddof=1) / np.sqrt(RECORDS)
        lo, hi = (1 - SIGMA_ACCURACY) ** 2, (1 + SIGMA_ACCURACY) ** 2
        assert lo - 5 * se_ms < ms < hi + 5 * se_ms, (scheme, j, ms, se_ms)


def test_gaussian_model_draws_on_its_generator_and_device(kernel):
    acq = spibench.Acquisition(kernel, "double_arm", 0.25)
    phys = TracedSinglePixel(acq, noise="gaussian", kernel=kernel, seed=4)
    assert isinstance(phys.noise_model, BenchGaussianNoise)
    assert "BenchGaussianNoise" in repr(phys)
    x = torch.rand(3, 1, *acq.grid)
    a = phys(x)
    phys.noise_model.rng.manual_seed(4)
    b = phys(x)
    assert torch.equal(a, b) and a.dtype == torch.float32
    clean = phys.A(x)
    assert not torch.equal(a, clean)
    # Its σ in the physics' units is the volts' divided by the scale.
    v = phys.to_volts(clean).double()
    s = phys.noise_model.sigma(clean.double(), x.mean(dim=(1, 2, 3)).double())
    sv = phys.noise_model.variance_v(v, x.mean(dim=(1, 2, 3)).double()).sqrt()
    assert torch.allclose(s * phys.scale.double(), sv, rtol=1e-5)
    phys.to("meta")
    assert all(b.device.type == "meta" for b in phys.noise_model.buffers())


def test_the_calibrated_scheme_is_refused(kernel):
    acq = spibench.Acquisition(kernel, "double_arm_calibrated", 0.25)
    with pytest.raises(spibench.InputError, match="own light"):
        BenchGaussianNoise.fit(acq)


def test_measured_moments(kernel):
    """The calibration's moments: one row per object, every measurement noisy."""
    acq = spibench.Acquisition(kernel, "traditional", 0.25)
    obj = held_out_objects(acq.grid)[:1]
    v, mean, var = measured_moments(acq, obj, 8, 3)
    assert v.shape == mean.shape == var.shape == (1, acq.measurements)
    assert np.all(var > 0)
