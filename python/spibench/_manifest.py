"""The checks of a dataset manifest read back from disk (README, "What spibench trusts"): a
manifest is a file spibench did not write in this process, so every name and path in it is
checked before any other file of the folder is opened. The same rules as the library's
(`dataset::check`) and examples/dataset_numpy.py: a shard folder is exactly shard_NNNNNN of its
own index, an array name is one the manifest's schemes and ratios allow, a file is NAME.npy,
and nothing leads out of the folder (absolute paths, `..`, symbolic links)."""

import os
import re

_error = ValueError  # replaced by spibench.InputError when the package imports this module

#: The acquisition schemes, as the command line and the manifests name them.
SCHEMES = (
    "traditional",
    "single_arm_complementary",
    "double_arm",
    "secondary_complementary_balancing",
    "traditional_zero_mean",
    "double_arm_calibrated",
    "double_arm_offset",
)
SEQUENCES = ("base", "complementary", "calibrated_base")
FIXED = {"sample", "object", "k", "b", "bench", "deviations", "dmd_image"}
COPIES = {"spec_file": "spec.ron", "bench_file": "bench.ron", "tolerance_file": "tolerances.ron"}


def _refuse(path, field, why):
    raise _error(f"{path}, field `{field}`: {why}; refusing to read this dataset")


def allowed_names(m, path="manifest.json"):
    """The array names a manifest with these schemes and ratios may hold (as spibench's)."""
    names = set(FIXED)
    for i, s in enumerate(m["schemes"]):
        if s not in SCHEMES:
            _refuse(path, f"schemes[{i}]", f"{s!r} is not a scheme of spibench")
        for r in m["ratios"]:
            for kind in ("meas", "recon", "score"):
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
    prov = m["provenance"]
    for key, want in COPIES.items():
        got = prov.get(key)
        if got != want and not (key == "tolerance_file" and got is None):
            _refuse(path, f"provenance.{key}", f"must be {want!r}, not {got!r}")
    if m.get("patterns_file") not in (None, "patterns.npy"):
        _refuse(path, "patterns_file", f"must be 'patterns.npy', not {m['patterns_file']!r}")
    allowed = allowed_names(m, path)
    schema = [a["name"] for a in m["schema"]]
    for i, name in enumerate(schema):
        if not isinstance(name, str) or name not in allowed or schema.index(name) != i:
            _refuse(path, f"schema[{i}].name", f"{name!r} is not an array of this dataset")
    for i, s in enumerate(m["shards"]):
        want = "shard_%06d" % s["index"]
        if s["dir"] != want:
            _refuse(path, f"shards[{i}].dir", f"the folder of shard {s['index']} is {want!r}, not {s['dir']!r}")
        _inside(root, s["dir"], path, f"shards[{i}].dir")
        if [f["name"] for f in s["files"]] != schema:
            _refuse(path, f"shards[{i}].files", "the files are not the schema's arrays")
        for k, f in enumerate(s["files"]):
            if f["file"] != f["name"] + ".npy":
                _refuse(path, f"shards[{i}].files[{k}].file", f"{f['file']!r} is not {f['name'] + '.npy'!r}")
            _inside(root, os.path.join(s["dir"], f["file"]), path, f"shards[{i}].files[{k}].file")
    return m
