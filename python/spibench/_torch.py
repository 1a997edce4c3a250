"""``torch.utils.data.Dataset`` over a spibench dataset folder (needs torch)."""

from __future__ import annotations

import numpy as np
import torch

from . import InputError, dataset_array_name


class MeasurementDataset(torch.utils.data.Dataset):
    """Sample s as (measurement, dmd_image, object), float32 tensors:

    - measurement: the recorded y (M,) of ``meas_SCHEME_rRATIO`` (V);
    - dmd_image: the light the measurement sees on the DMD units, x_j (W), (1, down, across):
      the dataset's ``dmd_image`` when written, else the kernel product of the object;
    - object: the ideal object on the kernel grid (transmittance), (1, H, W).
    """

    def __init__(self, dataset, scheme: str, ratio: float):
        name = dataset_array_name("meas", scheme, ratio)
        if name not in dataset.names:
            raise InputError(f"argument `scheme`/`ratio`: the dataset has no {name}")
        self.y = dataset.array(name)
        self.objects = dataset.array("object")
        if "dmd_image" in dataset.names:
            self.dmd = dataset.array("dmd_image")
        else:
            self.dmd = dataset.kernel().dmd_light(np.asarray(self.objects))

    def __len__(self) -> int:
        return len(self.y)

    def __getitem__(self, s: int):
        f = lambda a: torch.from_numpy(np.array(a, dtype=np.float32))  # noqa: E731
        return f(self.y[s]), f(self.dmd[s])[None], f(self.objects[s])[None]
