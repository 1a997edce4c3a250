"""Bad input raises InputError (a ValueError) naming the path or the argument."""

from __future__ import annotations

import numpy as np
import pytest

import spibench
from spibench import InputError


def test_input_error_is_a_value_error():
    assert issubclass(InputError, ValueError)


def test_unknown_variable_path(paper):
    with pytest.raises(InputError, match="detectors.minus.nonsense_mm"):
        paper.set({"detectors.minus.nonsense_mm": 1.0})
    with pytest.raises(InputError, match="detectors.minus.decenter_mm.x"):
        paper.set({"detectors.minus.decenter_mm.x": float("nan")})


def test_bad_bench_file_is_located(tmp_path):
    p = tmp_path / "bad.ron"
    p.write_text("(\n  band_nm: (350.0, \"x\"),\n)\n")
    with pytest.raises(InputError) as e:
        spibench.Bench.load(p)
    assert str(p) in str(e.value) and "line" in str(e.value)
    with pytest.raises(OSError):
        spibench.Bench.load(tmp_path / "missing.ron")


def test_arrays(kernel):
    acq = spibench.Acquisition(kernel, "double_arm", 0.05)
    x = np.zeros(acq.grid)
    with pytest.raises(InputError, match="`x`.*shape"):
        acq.apply(np.zeros((5, 5)))
    with pytest.raises(InputError, match="`x`.*dtype"):
        acq.apply(x.astype(complex))
    with pytest.raises(InputError, match="`x`.*dtype"):
        acq.apply(np.array([["a"] * 12] * 12))
    bad = x.copy()
    bad[3, 4] = np.nan
    with pytest.raises(InputError, match=r"`x`.*\(3, 4\).*not finite"):
        acq.forward(bad)
    with pytest.raises(InputError, match="`y`"):
        acq.adjoint(np.zeros(acq.measurements + 1))
    with pytest.raises(InputError, match="`seed`"):
        acq.forward(np.stack([x, x]), seed=[1])
    with pytest.raises(InputError, match="`objects`"):
        kernel.dmd_light(np.zeros((2, 3)))
    # float32 input is converted, not refused.
    assert acq.apply(x.astype(np.float32)).shape == (acq.measurements,)


def test_arguments(paper, kernel):
    with pytest.raises(InputError, match="scheme"):
        spibench.Acquisition(kernel, "nope", 0.1)
    with pytest.raises(InputError, match="ratio"):
        spibench.Acquisition(kernel, "double_arm", 1.5)
    with pytest.raises(InputError, match="rays"):
        paper.trace(rays=-1)
    with pytest.raises(InputError, match="threads"):
        paper.trace(rays=10, threads=0)
    with pytest.raises(InputError, match="chart"):
        paper.kernel(grid=(4, 4), field_mm=1.0, rays=1024, chart="nope")
    with pytest.raises(InputError, match="field_mm"):
        paper.kernel(grid=(4, 4), field_mm=-1.0, rays=1024)
    with pytest.raises(InputError, match="no manifest"):
        spibench.open_dataset("/nonexistent")
