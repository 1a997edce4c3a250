"""The dataset folder's contract: the package reads manifests by the library's rules
(`dataset::contract`), and examples/dataset_numpy.py, which keeps its own reader so that it
needs numpy alone, holds the same tables and refuses the same manifests."""

from __future__ import annotations

import importlib.util
import json
import shutil

import pytest

import spibench
from spibench import InputError, _spibench
from conftest import REPO

CONTRACT = _spibench.dataset_contract()


@pytest.fixture(scope="module")
def reader():
    """examples/dataset_numpy.py as a module."""
    spec = importlib.util.spec_from_file_location("dataset_numpy", REPO / "examples" / "dataset_numpy.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_numpy_reader_holds_the_librarys_tables(reader):
    assert reader.FORMAT == CONTRACT["format"]
    assert reader.MANIFEST == CONTRACT["manifest"]
    assert reader.COPIES == CONTRACT["copies"]
    assert reader.PATTERNS == CONTRACT["patterns"]
    assert reader.FIXED == set(CONTRACT["sample_arrays"])
    assert reader.CELL_KINDS == tuple(CONTRACT["cell_arrays"])
    assert reader.SEQUENCES == tuple(CONTRACT["sequences"])
    assert reader.SCHEMES == set(CONTRACT["schemes"]) == set(spibench.SCHEMES)
    for i in (0, 7, 123456, 1234567):
        assert reader.SHARD_DIR % i == _spibench.dataset_shard_dir(i)
    assert reader.ARRAY_FILE % "object" == "object.npy"


@pytest.mark.parametrize("ratios", [[0.05], [0.1, 0.25, 1.0], [0.123456, 0.00005, 0.03125]])
def test_the_numpy_reader_allows_the_librarys_array_names(reader, ratios):
    schemes = list(spibench.SCHEMES)
    m = {"schemes": schemes, "ratios": ratios}
    assert reader.allowed_names(m) == set(_spibench.dataset_array_names(schemes, ratios))
    for kind in CONTRACT["cell_arrays"]:
        for r in ratios:
            name = spibench.dataset_array_name(kind, "double_arm", r)
            assert name in reader.allowed_names(m), name


def test_array_names_are_checked():
    assert spibench.dataset_array_name("meas", "double_arm", 0.05) == "meas_double_arm_r0.0500"
    with pytest.raises(InputError, match="kind"):
        spibench.dataset_array_name("nope", "double_arm", 0.05)
    with pytest.raises(InputError, match="scheme"):
        spibench.dataset_array_name("meas", "nope", 0.05)
    with pytest.raises(InputError, match="ratio"):
        spibench.dataset_array_name("meas", "double_arm", 0.0)


TAMPERINGS = [
    ("shards[0].dir", lambda m: m["shards"][0].__setitem__("dir", "../outside/evil")),
    ("shards[0].dir", lambda m: m["shards"][0].__setitem__("dir", "shard_000001")),
    ("schema[0].name", lambda m: m["schema"][0].__setitem__("name", "../../../outside/evil/sample")),
    ("schema[1].name", lambda m: m["schema"][1].__setitem__("name", "meas_double_arm_r0.5000")),
    ("schemes[0]", lambda m: m["schemes"].__setitem__(0, "../evil")),
    ("shards[0].files[0].file", lambda m: m["shards"][0]["files"][0].__setitem__("file", "x.npy")),
    ("provenance.spec_file", lambda m: m["provenance"].__setitem__("spec_file", "/etc/passwd")),
    ("patterns_file", lambda m: m.__setitem__("patterns_file", "../p.npy")),
    ("format", lambda m: m.__setitem__("format", "other")),
]


@pytest.mark.parametrize("field, edit", TAMPERINGS)
def test_both_readers_refuse_a_tampered_manifest_naming_the_field(dataset, reader, tmp_path,
                                                                   field, edit):
    ds, _ = dataset
    copy = tmp_path / "copy"
    shutil.copytree(ds.path, copy)
    path = copy / CONTRACT["manifest"]
    m = json.loads(path.read_text())
    edit(m)
    path.write_text(json.dumps(m))
    pattern = "field `" + field.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.") + "`"
    with pytest.raises(InputError, match=pattern):
        spibench.open_dataset(copy)
    with pytest.raises(reader.UntrustedManifest, match=pattern):
        reader.manifest(str(copy))


def test_both_readers_read_the_same_manifest(dataset, reader):
    ds, _ = dataset
    m = reader.manifest(ds.path)
    assert [a["name"] for a in m["schema"]] == ds.names
    assert m["shards"] == ds.manifest["shards"] and m["seed"] == ds.seed


def test_the_manifest_names_the_dmd_model(dataset, reader):
    """The shipped paper bench traces its DMD as a grating; the manifest says so."""
    ds, _ = dataset
    assert ds.manifest["dmd_model"] == "diffractive"
    assert reader.manifest(ds.path)["dmd_model"] == "diffractive"
