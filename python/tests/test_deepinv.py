"""The deepinv adapter (skipped without torch and deepinv)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
dinv = pytest.importorskip("deepinv")

import spibench  # noqa: E402
from conftest import FIELD_MM  # noqa: E402
from spibench.deepinv import TracedSinglePixel  # noqa: E402


@pytest.fixture(scope="module")
def physics(kernel):
    """SCB at 25 % with the bench's noise, in float64 through the kernel's sparse matrices."""
    acq = spibench.Acquisition(kernel, "secondary_complementary_balancing", 0.25)
    phys = TracedSinglePixel(acq, noise="bench", seed=3, max_iter=200, tol=1e-8, kernel=kernel,
                             dtype=torch.float64)
    phys.operator_kernel = kernel
    return phys


def test_deepinv_adjointness(physics):
    err = physics.adjointness_test(img_size=(1,) + physics.acquisition.grid, dtype=torch.float64,
                                   num_samples=4)
    assert float(err) < 1e-10, float(err)


@pytest.mark.parametrize("with_kernel", [True, False], ids=["csr", "matrix"])
def test_float32_by_default_and_equal_to_the_library(kernel, with_kernel):
    acq = spibench.Acquisition(kernel, "double_arm", 0.25)
    phys = TracedSinglePixel(acq, noise=None, kernel=kernel if with_kernel else None)
    assert phys.offset.dtype == torch.float32
    x = np.random.default_rng(4).random((3, 1) + acq.grid)
    y = phys.A(torch.from_numpy(x).float())
    assert y.dtype == torch.float32 and y.shape == (3, acq.measurements)
    want = acq.apply(x[:, 0])
    # Within float32 rounding of the terms before they cancel (test_torch_operator.py).
    got = (y * phys.scale).double().numpy()
    assert np.linalg.norm(got - want) / np.linalg.norm(want) < 1e-3
    err = phys.adjointness_test(img_size=(1,) + acq.grid, dtype=torch.float32, num_samples=4)
    assert float(err) < 1e-5, float(err)
    noisy = TracedSinglePixel(acq, kernel=kernel)
    assert noisy(torch.from_numpy(x).float()).dtype == torch.float32


def test_to_moves_the_operator(physics):
    phys = TracedSinglePixel(physics.acquisition, noise=None, kernel=None, dtype=torch.float64)
    phys.to("meta")
    assert phys.offset.device.type == "meta"
    assert all(b.device.type == "meta" for b in phys.buffers())
    names = set(phys.state_dict())
    assert "operator.offset" in names and "operator.matrix" in names


def test_gradients_go_through_the_adjoint(physics):
    x = torch.rand(2, 1, *physics.acquisition.grid, dtype=torch.float64, requires_grad=True)
    y = torch.randn(2, physics.acquisition.measurements, dtype=torch.float64)
    (physics.A(x) * y).sum().backward()
    want = physics.A_adjoint(y)
    assert torch.allclose(x.grad, want, rtol=1e-12, atol=1e-12 * float(want.abs().max()))


def test_offset_and_noise(physics):
    x = torch.rand(2, 1, *physics.acquisition.grid, dtype=torch.float64)
    y = physics(x)
    clean = physics.A(x)
    assert y.shape == clean.shape
    rel = float(torch.linalg.norm(y - clean) / torch.linalg.norm(clean))
    assert 0 < rel < 0.05, rel
    raw = physics.simulate(x, seed=1)
    assert torch.allclose(physics.remove_offset(raw), (raw - physics.offset) / physics.scale)
    assert torch.allclose(physics.to_volts(physics.remove_offset(raw)), raw)


def test_normalised_by_default(physics):
    acq = physics.acquisition
    assert float(physics.scale) == pytest.approx(acq.operator_norm(), rel=1e-12)
    x = torch.rand(1, 1, *acq.grid, dtype=torch.float64)
    norm2 = float(physics.compute_sqnorm(x, max_iter=500, tol=1e-10, verbose=False))
    assert norm2 == pytest.approx(1.0, rel=1e-6)
    volts = TracedSinglePixel(acq, noise=None, normalise=False, dtype=torch.float64,
                              kernel=physics.operator_kernel)
    assert float(volts.scale) == 1.0
    want = volts.A(x)
    assert torch.allclose(physics.A(x) * physics.scale, want, rtol=1e-12,
                          atol=1e-12 * float(want.abs().max()))


def test_printed_form_shows_the_bench_noise(physics):
    text = repr(physics)
    assert "BenchSimulation" in text and "ZeroNoise" not in text, text
    with pytest.raises(spibench.InputError, match="physics\\(x\\)"):
        physics.noise(torch.zeros(1, physics.acquisition.measurements, dtype=torch.float64))
    assert "ZeroNoise" in repr(TracedSinglePixel(physics.acquisition, noise=None))


def _tv(phys, y, lam):
    model = dinv.optim.PGD(data_fidelity=dinv.optim.data_fidelity.L2(),
                           prior=dinv.optim.prior.TVPrior(), lambda_reg=lam, stepsize=1.0,
                           max_iter=100)
    return model(y, phys)


def test_deepinv_tv_with_its_usual_weight(physics):
    """deepinv's TV-PGD with λ = 1e-3 and step 1 on the normalised physics reconstructs a
    traced SCB measurement (bench noise) as well as least squares does, within 1 dB; on the
    physics in volts (‖A‖² ≈ 0.06 here) the same weight over-smooths it (3 dB worse at least)."""
    h, w = physics.acquisition.grid
    obj = torch.zeros(1, 1, h, w, dtype=torch.float64)
    obj[..., 2:10, 3:6] = 1.0
    obj[..., 8:11, 7:11] = 0.5
    y = physics(obj)
    psnr = dinv.metric.PSNR()
    tv = float(psnr(_tv(physics, y, 1e-3).clamp(0, 1), obj))
    ls = float(psnr(physics.A_dagger(y).clamp(0, 1), obj))
    volts = TracedSinglePixel(physics.acquisition, noise=None, kernel=None, normalise=False,
                              dtype=torch.float64)
    tv_volts = float(psnr(_tv(volts, physics.to_volts(y) - volts.offset, 1e-3).clamp(0, 1), obj))
    print(f"TV λ=1e-3: normalised {tv:.1f} dB, in volts {tv_volts:.1f} dB; least squares {ls:.1f} dB")
    assert tv > ls - 1.0, (tv, ls)
    assert tv_volts < tv - 3.0, (tv_volts, tv)


def test_deepinv_solver_reconstructs_a_traced_measurement(physics):
    h, w = physics.acquisition.grid
    obj = torch.zeros(1, 1, h, w, dtype=torch.float64)
    obj[..., 2:10, 3:6] = 1.0
    obj[..., 8:11, 7:11] = 0.5
    y = physics(obj)
    x_hat = physics.A_dagger(y)
    err = float(torch.linalg.norm(x_hat - obj) / torch.linalg.norm(obj))
    assert err < 0.1, err
    psnr = float(dinv.metric.PSNR()(x_hat.clamp(0, 1), obj))
    print(f"deepinv A_dagger on a traced SCB measurement (bench noise): rel err {err:.4f}, PSNR {psnr:.1f} dB")


def test_torch_dataset(dataset):
    """(x, y) by default, y what the normalised physics models; other records by name."""
    ds, _ = dataset
    td = ds.torch_dataset("double_arm", 0.05)
    x, y = td[1]
    acq = ds.acquisition("double_arm", 0.05)
    assert y.shape == (acq.measurements,) and x.shape == (1, 12, 12) and len(td) == 3
    phys = TracedSinglePixel(acq, noise=None, dtype=torch.float64)
    meas = torch.from_numpy(np.array(ds.array("meas_double_arm_r0.0500")[1]))
    want = phys.remove_offset(meas[None])[0]
    assert torch.allclose(y.double(), want, rtol=1e-6, atol=1e-6 * float(want.abs().max()))
    assert torch.equal(x[0], torch.from_numpy(np.array(ds.array("object")[1], dtype=np.float32)))
    v, d = ds.torch_dataset("double_arm", 0.05, records=("measurement_v", "dmd_light_w"))[1]
    assert torch.equal(v, meas.float()) and d.shape == (1,) + acq.units
    with pytest.raises(spibench.InputError, match="records"):
        ds.torch_dataset("double_arm", 0.05, records=("image",))


def test_dmd_light_shows_the_object_rotated(paper):
    """The imaging lens inverts: the light on the DMD units (one object pixel per unit here)
    correlates with the object rotated by 180°, not with the object as it lies."""
    kernel = paper.kernel(grid=paper.check(), field_mm=FIELD_MM, rays=8192, seed=2)
    h, w = kernel.grid
    obj = np.zeros((h, w))
    obj[: h // 2, : w // 3] = 1.0
    obj[h // 2:, w // 2:] = 0.4
    light = kernel.dmd_light(obj)
    small = obj
    corr = lambda a, b: float(np.corrcoef(a.ravel(), b.ravel())[0, 1])  # noqa: E731
    assert corr(light, small[::-1, ::-1]) > 0.5 > corr(light, small)
