"""examples/train_deepinv.py at its CI size: it runs, and each network's training loss falls
(skipped without torch and deepinv)."""

from __future__ import annotations

import importlib.util
import math

import pytest

pytest.importorskip("torch")
pytest.importorskip("deepinv")

from conftest import REPO  # noqa: E402


def test_train_deepinv_tiny(tmp_path):
    spec = importlib.util.spec_from_file_location("train_deepinv", REPO / "examples" / "train_deepinv.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    r = mod.run("tiny", seed=0, folder=str(tmp_path))
    assert set(r["losses"]) == {"ideal", "traced", "drawn"}
    for name, losses in r["losses"].items():
        assert len(losses) == r["epochs"] and all(math.isfinite(v) for v in losses)
        assert losses[-1] < losses[0], (name, losses)
    for v in r["psnr_db"].values():
        assert math.isfinite(v["paper_bench"]) and math.isfinite(v["drawn_benches"])


def test_dataset_torch_example_gives_x_then_y(dataset):
    """examples/dataset_torch.py reads a dataset as (object, recorded volts) pairs."""
    import sys

    import numpy as np
    import torch

    ds, _ = dataset
    sys.path.insert(0, str(REPO / "examples"))
    try:
        from dataset_torch import SpibenchDataset
    finally:
        sys.path.pop(0)
    td = SpibenchDataset(ds.path, measurement="meas_double_arm_r0.0500")
    x, y = td[2]
    assert len(td) == ds.samples and x.shape == (1, 12, 12)
    assert torch.equal(x[0], torch.from_numpy(np.array(ds.array("object")[2], dtype=np.float32)))
    want = np.array(ds.array("meas_double_arm_r0.0500")[2], dtype=np.float32)
    assert torch.equal(y, torch.from_numpy(want))
