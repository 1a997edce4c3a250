#!/usr/bin/env python3
"""A PyTorch Dataset over a spibench dataset folder (manifest.json + .npy shards), numpy and
torch only (the spibench package's own is ``spibench.open_dataset(dir).torch_dataset(...)``).

    ds = SpibenchDataset("out/dataset", measurement="meas_secondary_complementary_balancing_r0.2500")
    x, y = ds[0]           # object (float32, 1 x H x W), measurements (float32, volts as recorded)
    loader = torch.utils.data.DataLoader(ds, batch_size=32, shuffle=True)

(x, y) is the order of deepinv's trainers. The measurements are the recorded volts; the
package's torch_dataset gives them as its deepinv physics models them (offset removed,
normalised).

Shards are memory-mapped (np.load(..., mmap_mode="r")), so the dataset can be larger than RAM.
The manifest is read by dataset_numpy.manifest, which refuses shard folders, array names and
paths that lead out of the dataset folder (as spibench does) before any array is opened.
"""
import bisect
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from dataset_numpy import ARRAY_FILE, CELL_KINDS  # noqa: E402
from dataset_numpy import manifest as checked_manifest  # noqa: E402


class SpibenchDataset(torch.utils.data.Dataset):
    def __init__(self, root, measurement=None):
        self.manifest = checked_manifest(root)
        names = [a["name"] for a in self.manifest["schema"]]
        meas = CELL_KINDS[0] + "_"
        self.measurement = measurement or next(n for n in names if n.startswith(meas))
        if self.measurement not in names:
            raise ValueError(f"{self.measurement!r} is not an array of this dataset: {names}")
        shards = sorted(self.manifest["shards"], key=lambda s: s["index"])
        self.y, self.x, self.starts = [], [], []
        n = 0
        for s in shards:
            d = os.path.join(root, s["dir"])
            self.y.append(np.load(os.path.join(d, ARRAY_FILE % self.measurement), mmap_mode="r"))
            self.x.append(np.load(os.path.join(d, ARRAY_FILE % "object"), mmap_mode="r"))
            self.starts.append(n)
            n += s["samples"]
        self.n = n

    def __len__(self):
        return self.n

    def __getitem__(self, i):
        k = bisect.bisect_right(self.starts, i) - 1
        j = i - self.starts[k]
        x = torch.from_numpy(np.array(self.x[k][j], dtype=np.float32))[None]
        y = torch.from_numpy(np.array(self.y[k][j], dtype=np.float32))
        return x, y


if __name__ == "__main__":
    import sys

    ds = SpibenchDataset(sys.argv[1])
    x, y = ds[0]
    print(len(ds), "samples;", "object", tuple(x.shape), ds.measurement, tuple(y.shape))
