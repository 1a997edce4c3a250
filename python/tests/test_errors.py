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
    # The kernel's arguments are checked by the library's one kernel builder, with the bounds of
    # a dataset spec's `kernel:` section.
    with pytest.raises(InputError, match=r"field `chart`.*no chart named \"nope\".*\"chart\""):
        paper.kernel(grid=(4, 4), field_mm=1.0, rays=2048, chart="nope")
    with pytest.raises(InputError, match="field `field_mm`"):
        paper.kernel(grid=(4, 4), field_mm=-1.0, rays=2048)
    with pytest.raises(InputError, match="field `field_mm`"):
        paper.kernel(grid=(4, 4), field_mm=(1.0, float("nan")), rays=2048)
    with pytest.raises(InputError, match="field `grid`.*from 1 to 1024"):
        paper.kernel(grid=(0, 4), field_mm=1.0, rays=2048)
    with pytest.raises(InputError, match="argument `grid`"):
        paper.kernel(grid=(-1, 4), field_mm=1.0, rays=2048)
    with pytest.raises(InputError, match="field `rays`.*from 2048"):
        paper.kernel(grid=(4, 4), field_mm=1.0, rays=1024)
    with pytest.raises(InputError, match="no manifest"):
        spibench.open_dataset("/nonexistent")


@pytest.mark.parametrize(
    "field, edit",
    [
        ("shards[0].dir", lambda m: m["shards"][0].__setitem__("dir", "../outside/evil")),
        ("shards[0].dir", lambda m: m["shards"][0].__setitem__("dir", "/etc")),
        ("schema[0].name", lambda m: m["schema"][0].__setitem__("name", "../../../outside/evil/sample")),
    ],
)
def test_a_manifest_leading_out_of_its_folder_is_refused(dataset, tmp_path, field, edit):
    """The manifest is untrusted: names that leave the folder are refused before any read."""
    import json
    import shutil

    ds, _ = dataset
    copy = tmp_path / "copy"
    shutil.copytree(ds.path, copy)
    m = json.loads((copy / "manifest.json").read_text())
    edit(m)
    (copy / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(InputError, match=field.replace("[", r"\[").replace("]", r"\]")):
        spibench.open_dataset(copy)


def test_a_symbolic_link_out_of_the_folder_is_refused(dataset, tmp_path):
    import shutil

    ds, _ = dataset
    copy = tmp_path / "copy"
    shutil.copytree(ds.path, copy)
    outside = tmp_path / "outside"
    shutil.move(str(copy / "shard_000000"), outside)
    (copy / "shard_000000").symlink_to(outside)
    with pytest.raises(InputError, match=r"shards\[0\]\.dir"):
        spibench.open_dataset(copy)
