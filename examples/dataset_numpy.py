#!/usr/bin/env python3
"""Read a spibench dataset with numpy only.

    python3 examples/dataset_numpy.py DATASET_DIR [--check LINE | --validate]

Each shard's arrays are plain .npy files, memory-mapped here (np.load(..., mmap_mode="r")).
`load(dir)` returns a dict name -> list of memory-mapped shard arrays and the manifest;
`sample(dir, s)` gathers sample s. With --check, the "check:" line that `spibench dataset`
printed is compared with the arrays (used by CI).

A manifest may have been edited by someone else: `manifest(dir)` refuses, as spibench does,
any shard folder that is not exactly shard_NNNNNN of its index, any array name that the
manifest's schemes and ratios do not allow, any file that is not NAME.npy, and any path that
leads out of the folder through a symbolic link, before a single array is opened.

The names below are the dataset folder's contract as spibench defines it (its
`dataset::contract` module); the Python package's tests compare these tables with the
library's, so this reader needs numpy alone and still follows spibench.
"""
import hashlib
import json
import os
import re
import sys

FORMAT = "spibench-dataset-1"
MANIFEST = "manifest.json"
SCHEMES = {
    "traditional",
    "single_arm_complementary",
    "double_arm",
    "secondary_complementary_balancing",
    "traditional_zero_mean",
    "double_arm_calibrated",
    "double_arm_offset",
}
SEQUENCES = ("base", "complementary", "calibrated_base")
FIXED = {"sample", "object", "k", "b", "bench", "deviations", "dmd_image"}
CELL_KINDS = ("meas", "recon", "score")
COPIES = {"spec_file": "spec.ron", "bench_file": "bench.ron", "tolerance_file": "tolerances.ron"}
PATTERNS = "patterns.npy"
SHARD_DIR = "shard_%06d"
ARRAY_FILE = "%s.npy"


class UntrustedManifest(ValueError):
    """A manifest that names something outside its folder, or a name spibench never writes."""


def _refuse(path, field, why):
    raise UntrustedManifest(f"{path}, field `{field}`: {why}; refusing to read this dataset")


def allowed_names(m, path="manifest.json"):
    """The array names a manifest with these schemes and ratios may hold (as spibench's)."""
    names = set(FIXED)
    for i, s in enumerate(m["schemes"]):
        if s not in SCHEMES:
            _refuse(path, f"schemes[{i}]", f"{s!r} is not a scheme of spibench")
        for r in m["ratios"]:
            for kind in CELL_KINDS:
                names.add(f"{kind}_{s}_r{float(r):.4f}")
    names.update(f"scope_{q}" for q in SEQUENCES)
    return names


def _inside(root, rel, path, field):
    """rel below root, which must not lead out of root (symbolic links resolved)."""
    if os.path.isabs(rel) or any(p in ("", ".", "..") for p in re.split(r"[/\\]", rel)):
        _refuse(path, field, f"{rel!r} is not a plain name inside the folder")
    real_root = os.path.realpath(root)
    real = os.path.realpath(os.path.join(root, rel))
    if os.path.commonpath([real_root, real]) != real_root:
        _refuse(path, field, f"{rel!r} leads out of the folder (to {real})")
    return os.path.join(root, rel)


def checked(m, root, path="manifest.json"):
    """Checks every name and path of manifest m of folder root; returns m."""
    if m.get("format") != FORMAT:
        _refuse(path, "format", f"{m.get('format')!r} is not {FORMAT!r}")
    prov = m["provenance"]
    for key, want in COPIES.items():
        got = prov.get(key)
        if got != want and not (key == "tolerance_file" and got is None):
            _refuse(path, f"provenance.{key}", f"must be {want!r}, not {got!r}")
    if m.get("patterns_file") not in (None, PATTERNS):
        _refuse(path, "patterns_file", f"must be {PATTERNS!r}, not {m['patterns_file']!r}")
    allowed = allowed_names(m, path)
    schema = [a["name"] for a in m["schema"]]
    for i, name in enumerate(schema):
        if not isinstance(name, str) or name not in allowed or schema.index(name) != i:
            _refuse(path, f"schema[{i}].name", f"{name!r} is not an array of this dataset")
    for i, s in enumerate(m["shards"]):
        want = SHARD_DIR % s["index"]
        if s["dir"] != want:
            _refuse(path, f"shards[{i}].dir", f"the folder of shard {s['index']} is {want!r}, not {s['dir']!r}")
        _inside(root, s["dir"], path, f"shards[{i}].dir")
        if [f["name"] for f in s["files"]] != schema:
            _refuse(path, f"shards[{i}].files", "the files are not the schema's arrays")
        for k, f in enumerate(s["files"]):
            if f["file"] != ARRAY_FILE % f["name"]:
                _refuse(path, f"shards[{i}].files[{k}].file", f"{f['file']!r} is not {ARRAY_FILE % f['name']!r}")
            _inside(root, os.path.join(s["dir"], f["file"]), path, f"shards[{i}].files[{k}].file")
    return m


def manifest(root):
    """The manifest of dataset folder root, checked (see the module docstring)."""
    path = _inside(root, MANIFEST, os.path.join(root, MANIFEST), MANIFEST)
    with open(path) as f:
        return checked(json.load(f), root, path)


def load(root, verify=False):
    """name -> list of per-shard arrays (memory-mapped), in sample order, and the manifest."""
    import numpy as np

    m = manifest(root)
    arrays = {a["name"]: [] for a in m["schema"]}
    for shard in sorted(m["shards"], key=lambda s: s["index"]):
        for f in shard["files"]:
            path = os.path.join(root, shard["dir"], f["file"])
            if verify:
                with open(path, "rb") as fh:
                    if hashlib.sha256(fh.read()).hexdigest() != f["sha256"]:
                        raise ValueError(f"{path}: checksum differs from the manifest")
            arrays[f["name"]].append(np.load(path, mmap_mode="r"))
    return arrays, m


def sample(root, s, arrays=None, m=None):
    """Every array of sample s as a dict."""
    import numpy as np

    if arrays is None:
        arrays, m = load(root)
    k = s // m["shard_samples"]
    shards = sorted(m["shards"], key=lambda x: x["index"])
    pos = [i for i, x in enumerate(shards) if x["index"] == k]
    if not pos:
        raise IndexError(f"sample {s} is not in this folder")
    i = pos[0]
    return {name: np.asarray(a[i][s - shards[i]["first_sample"]]) for name, a in arrays.items()}


def check(root, line):
    """Compares the values of spibench's "check:" line with the arrays."""
    import numpy as np

    words = line.split()
    s = int(words[words.index("sample") + 1])
    values = dict(zip(words[3::2], words[4::2]))
    arrays, m = load(root, verify=True)
    x = sample(root, s, arrays, m)
    for a in m["schema"]:
        want = tuple(a["sample_shape"])
        assert x[a["name"]].shape == want, (a["name"], x[a["name"]].shape, want)
    got_sum = float(np.sum(x["object"]))
    assert abs(got_sum - float(values["object_sum"])) <= 1e-9 * max(1.0, abs(got_sum)), got_sum
    meas = [k for k in values if k.startswith("meas_")][0]
    name = meas.split("[")[0]
    assert x[name][0] == float(values[meas]), (x[name][0], values[meas])
    assert x["k"][0] == float(values["k+"]), (x["k"][0], values["k+"])
    assert int(x["sample"]) == s
    print(f"dataset_numpy: {len(m['shards'])} shards, sample {s} matches spibench's values")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[2] == "--validate":
        # Only the manifest's names and paths (no numpy needed).
        try:
            manifest(sys.argv[1])
        except UntrustedManifest as e:
            sys.exit(str(e))
        print("dataset_numpy: the manifest names only plain files inside the folder")
    elif len(sys.argv) >= 4 and sys.argv[2] == "--check":
        check(sys.argv[1], " ".join(sys.argv[3:]))
    elif len(sys.argv) == 2:
        arrays, m = load(sys.argv[1])
        for a in m["schema"]:
            n = sum(x.shape[0] for x in arrays[a["name"]])
            print(f"{a['name']:40s} {a['dtype']} {n} x {a['sample_shape']} [{a['units']}]")
    else:
        sys.exit(__doc__)
