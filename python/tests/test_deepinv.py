"""The deepinv adapter (skipped without torch and deepinv)."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
dinv = pytest.importorskip("deepinv")

import spibench  # noqa: E402
from spibench.deepinv import TracedSinglePixel  # noqa: E402


@pytest.fixture(scope="module")
def physics(kernel):
    """SCB at 25 % with the bench's noise, in float64 through the kernel's sparse matrices."""
    acq = spibench.Acquisition(kernel, "secondary_complementary_balancing", 0.25)
    return TracedSinglePixel(acq, noise="bench", seed=3, max_iter=200, tol=1e-8, kernel=kernel,
                             dtype=torch.float64)


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
    assert np.linalg.norm(y.double().numpy() - want) / np.linalg.norm(want) < 1e-3
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
    assert torch.allclose(x.grad, physics.A_adjoint(y), rtol=1e-12, atol=0)


def test_offset_and_noise(physics):
    x = torch.rand(2, 1, *physics.acquisition.grid, dtype=torch.float64)
    y = physics(x)
    clean = physics.A(x)
    assert y.shape == clean.shape
    rel = float(torch.linalg.norm(y - clean) / torch.linalg.norm(clean))
    assert 0 < rel < 0.05, rel
    raw = physics.simulate(x, seed=1)
    assert torch.allclose(physics.remove_offset(raw), raw - physics.offset)


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
    ds, _ = dataset
    td = ds.torch_dataset("double_arm", 0.05)
    y, dmd, obj = td[1]
    assert y.shape == (ds.acquisition("double_arm", 0.05).measurements,)
    assert dmd.shape[0] == 1 and obj.shape == (1, 12, 12)
    assert len(td) == 3
