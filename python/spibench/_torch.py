"""``torch.utils.data.Dataset`` over a spibench dataset folder (needs torch)."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np
import torch

from . import InputError, dataset_array_name

#: The records a sample can give, by name (see :class:`MeasurementDataset`).
RECORDS = ("object", "measurement", "measurement_v", "dmd_light_w")


class MeasurementDataset(torch.utils.data.Dataset):
    """Sample s as a tuple of float32 tensors, by default (object, measurement), the (x, y)
    pairs that deepinv's trainer and ``examples/dataset_torch.py`` use:

    - ``"object"``: the ideal object on the kernel grid (transmittance), (1, H, W);
    - ``"measurement"``: y of ``meas_SCHEME_rRATIO`` as deepinv's physics models it
      (:class:`spibench.deepinv.TracedSinglePixel`): the recorded volts with the offset y₀
      removed, divided by ``scale`` (default ‖A‖, the ``physics.scale`` of the normalised
      physics; 1 keeps volts), (M,);
    - ``"measurement_v"``: the recorded volts themselves (the calibrated scheme:
      dimensionless), (M,);
    - ``"dmd_light_w"``: the light on each DMD unit x_j (W), (1, down, across) in the DMD's
      own order (as every per-unit map of the package): the imaging lens inverts, so the
      object appears in it rotated by 180° (``torch.flip(d, (-2, -1))`` puts it in the
      object's orientation). The dataset's ``dmd_image`` when written, else the kernel product
      of the object.
    """

    def __init__(self, dataset, scheme: str, ratio: float,
                 records: Sequence[str] = ("object", "measurement"),
                 scale: Optional[float] = None):
        name = dataset_array_name("meas", scheme, ratio)
        if name not in dataset.names:
            raise InputError(f"argument `scheme`/`ratio`: the dataset has no {name}")
        if isinstance(records, str) or not all(r in RECORDS for r in records) or not records:
            raise InputError(f"argument `records`: a sequence of {RECORDS}, got {records!r}")
        if scale is not None and not (np.isfinite(scale) and scale > 0):
            raise InputError(f"argument `scale`: a positive number, got {scale!r}")
        self.records: Tuple[str, ...] = tuple(records)
        self.y = dataset.array(name)
        self.objects = dataset.array("object")
        self.offset = None
        self.scale = None if scale is None else float(scale)
        if "measurement" in self.records:
            if dataset.benches > 1:
                raise InputError(
                    "argument `records`: the samples of this dataset were measured through "
                    f"{dataset.benches} drawn benches, each with its own offset: take "
                    "\"measurement_v\" and the physics of its bench "
                    "(spibench.deepinv.TracedBenches.remove_offset)")
            acq = dataset.acquisition(scheme, ratio)
            self.offset = np.asarray(acq.offset)
            if self.scale is None:
                self.scale = acq.operator_norm()
        self.dmd = None
        if "dmd_light_w" in self.records:
            if "dmd_image" in dataset.names:
                self.dmd = dataset.array("dmd_image")
            else:
                self.dmd = dataset.kernel().dmd_light(np.asarray(self.objects))

    def __len__(self) -> int:
        return len(self.y)

    def _record(self, name: str, s: int) -> np.ndarray:
        if name == "object":
            return np.asarray(self.objects[s])[None]
        if name == "measurement":
            return (np.asarray(self.y[s]) - self.offset) / self.scale
        if name == "measurement_v":
            return np.asarray(self.y[s])
        return np.asarray(self.dmd[s])[None]

    def __getitem__(self, s: int):
        return tuple(torch.from_numpy(np.array(self._record(r, s), dtype=np.float32))
                     for r in self.records)
