"""The library's TVAL3 from Python."""

from __future__ import annotations

import numpy as np

import spibench


def test_reconstruct_a_traced_measurement(kernel):
    acq = spibench.Acquisition(kernel, "secondary_complementary_balancing", 0.25)
    obj = np.zeros(acq.grid)
    obj[2:10, 3:6] = 1.0
    y = acq.forward(obj, noise=False)
    r = spibench.reconstruct(y, acq)
    assert r.image.shape == acq.units
    assert r.iterations > 0 and r.stop in ("Tolerance", "MaxOuter", "MaxIterations")
    assert r.seconds >= 0 and np.isfinite(r.relative_residual)
    # SCB images the units' gains g₊ + g₋ (k'·x per unit): the image correlates with the
    # kernel's gain image (0.91 with this 8192-ray kernel; 0.98 at 65536 rays).
    v = obj.ravel()
    gains = sum(kernel.g_a[d] @ v + kernel.g0_a[d] for d in range(2)).reshape(acq.units)
    c = np.corrcoef(r.image.ravel(), gains.ravel())[0, 1]
    assert c > 0.85, c
