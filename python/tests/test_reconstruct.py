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
    # The image is the light on the units: it correlates with the kernel's DMD image.
    truth = kernel.dmd_light(obj)
    c = np.corrcoef(r.image.ravel(), truth.ravel())[0, 1]
    assert c > 0.9, c
