#!/usr/bin/env python3
"""Read a spibench dataset with numpy only.

    python3 examples/dataset_numpy.py DATASET_DIR [--check LINE]

Each shard's arrays are plain .npy files, memory-mapped here (np.load(..., mmap_mode="r")).
`load(dir)` returns a dict name -> list of memory-mapped shard arrays and the manifest;
`sample(dir, s)` gathers sample s. With --check, the "check:" line that `spibench dataset`
printed is compared with the arrays (used by CI).
"""
import hashlib
import json
import os
import sys

import numpy as np


def manifest(root):
    with open(os.path.join(root, "manifest.json")) as f:
        return json.load(f)


def load(root, verify=False):
    """name -> list of per-shard arrays (memory-mapped), in sample order, and the manifest."""
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
    if len(sys.argv) >= 4 and sys.argv[2] == "--check":
        check(sys.argv[1], " ".join(sys.argv[3:]))
    elif len(sys.argv) == 2:
        arrays, m = load(sys.argv[1])
        for a in m["schema"]:
            n = sum(x.shape[0] for x in arrays[a["name"]])
            print(f"{a['name']:40s} {a['dtype']} {n} x {a['sample_shape']} [{a['units']}]")
    else:
        sys.exit(__doc__)
