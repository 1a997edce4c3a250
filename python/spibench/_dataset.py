"""Dataset folders of ``spibench dataset``: made, opened (their manifest read and checked by
the library), their arrays as numpy, and the acquisitions that made them."""

from __future__ import annotations

import json
import os
from typing import List, Optional, Sequence

import numpy as np
import numpy.typing as npt

from . import _spibench
from ._acquisition import Acquisition
from ._checks import PathLike, _threads, _u64
from ._kernel import Kernel
from ._spibench import InputError


def dataset_noise_seed(seed: int, s: int) -> int:
    """The record seed (noise and drift) of sample ``s`` of a dataset whose spec seed is ``seed``."""
    return _spibench.dataset_noise_seed(_u64(seed, "seed"), _u64(s, "s"))


def dataset_array_name(kind: str, scheme: str, ratio: float) -> str:
    """The name of a dataset's array of kind ``kind`` (``"meas"``, ``"recon"`` or ``"score"``)
    for ``scheme`` at sampling ratio ``ratio``: ``meas_SCHEME_rRATIO``, the ratio with four
    decimals, as the library names it."""
    return _spibench.dataset_array_name(str(kind), str(scheme), float(ratio))


def make_dataset(spec: PathLike, out: PathLike, threads: Optional[int] = None) -> int:
    """Makes the dataset of ``spec`` in ``out``, as ``spibench dataset SPEC --out OUT``; returns
    the shards written."""
    return _spibench.make_dataset(os.fspath(spec), os.fspath(out), _threads(threads))


class OpenDataset:
    """A dataset folder: the manifest, every array as numpy (memory-mapped, shards
    concatenated lazily by :meth:`array`), and the acquisitions that made it."""

    def __init__(self, path: PathLike):
        self.path = os.fspath(path)
        name = _spibench.dataset_contract()["manifest"]
        mpath = os.path.join(self.path, name)
        if not os.path.lexists(mpath):
            raise InputError(f"{mpath}: no {name}: not a spibench dataset folder")
        # Read and checked by the library's rules: every name and path in it, before any other
        # file of the folder is opened.
        self.manifest = json.loads(_spibench.read_dataset_manifest(self.path))
        self.shards = sorted(self.manifest["shards"], key=lambda s: s["index"])
        self._inner = None

    @property
    def names(self) -> List[str]:
        """The array names of every sample (``object``, ``meas_SCHEME_rRATIO``, ``k``, …)."""
        return [a["name"] for a in self.manifest["schema"]]

    @property
    def samples(self) -> int:
        """The number of samples, over all shards."""
        return sum(s["samples"] for s in self.shards)

    @property
    def seed(self) -> int:
        """The spec's seed (see :func:`dataset_noise_seed`)."""
        return int(self.manifest["seed"])

    @property
    def forward_model(self) -> str:
        """The forward model of the measurements, in words."""
        return (
            "y = forward(t): the object t (transmittance on the kernel grid) lights the DMD "
            "units through the traced kernel, x_j = Σ_i X[j,i]·t_i + x0_j (W) and "
            "g±_j = Σ_i G±[j,i]·t_i + g0±_j (A); each frame's pattern P gives the diode light "
            "L₊ = P·g₊ + c₊, L₋ = Σg₋ − P·g₋ + c₋ (A); the detector's outputs (V) are recorded "
            "with drift and noise and each scheme differences its frames. Noise-free, "
            "y ≈ A t + y₀ (Acquisition.apply, Acquisition.offset)."
        )

    def shard_files(self, name: str) -> List[str]:
        """The file of array ``name`` in each shard, in sample order."""
        if name not in self.names:
            raise InputError(f"argument `name`: no array {name!r}; the dataset has {self.names}")
        return [
            os.path.join(self.path, s["dir"], next(f["file"] for f in s["files"] if f["name"] == name))
            for s in self.shards
        ]

    def array(self, name: str, mmap: bool = True) -> npt.NDArray[np.float64]:
        """Array ``name`` of every sample, shards concatenated (one shard: a memory map)."""
        parts = [np.load(p, mmap_mode="r" if mmap else None) for p in self.shard_files(name)]
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _rust(self):
        if self._inner is None:
            self._inner = _spibench.Dataset(self.path, None)
        return self._inner

    def acquisition(self, scheme: str, ratio: float) -> Acquisition:
        """The acquisition that made ``meas_SCHEME_rRATIO`` (the kernel traced again from the
        spec's rays and seed: the same kernel bit for bit). ``forward(objects, noise=True,
        seed=dataset.seed)`` of samples 0…N−1 gives their measurements."""
        return Acquisition._of(self._rust().acquisition(str(scheme), float(ratio)))

    def kernel(self) -> Kernel:
        """The dataset's object kernel, traced again from the spec (bit for bit the same); for
        benches drawn from a tolerance file, the nominal bench's (see :meth:`drawn_bench`)."""
        return Kernel(self._rust().kernel())

    @property
    def benches(self) -> int:
        """The benches the samples were measured through: 1 (the nominal bench), or for benches
        drawn from a tolerance file ⌈samples / samples_per_bench⌉ (sample s: bench
        ``array("bench")[s]``)."""
        return int(self._rust().benches)

    @property
    def deviation_names(self) -> List[str]:
        """The names of a drawn bench's deviations (tolerances, then compensators)."""
        return list(self._rust().deviation_names())

    def drawn_bench(self, t: int):
        """Drawn bench ``t`` of a dataset over benches drawn from a tolerance file, as the
        dataset measured its samples: (kernel, deviations), the kernel traced again with the
        spec's rays and seed (the dataset's bit for bit; one trace per call), the deviations in
        :attr:`deviation_names` order."""
        k, dev = self._rust().drawn_bench(_u64(t, "t"))
        return Kernel(k), np.asarray(dev, dtype=np.float64)

    def acquisition_on(self, kernel: Kernel, scheme: str, ratio: float) -> Acquisition:
        """The acquisition of ``meas_SCHEME_rRATIO`` through ``kernel`` (a drawn bench's, from
        :meth:`drawn_bench`), with the dataset's patterns and schemes recorded together."""
        if not isinstance(kernel, Kernel):
            raise InputError("argument `kernel`: a spibench.Kernel is needed")
        return Acquisition._of(self._rust().acquisition_on(kernel._k, str(scheme), float(ratio)))

    def torch_dataset(self, scheme: str, ratio: float,
                      records: Sequence[str] = ("object", "measurement"),
                      scale: Optional[float] = None):
        """A ``torch.utils.data.Dataset`` of (object, measurement) per sample, deepinv's
        (x, y), float32: the object on the kernel grid (1, H, W) and the measurement of
        ``meas_SCHEME_rRATIO`` as :class:`spibench.deepinv.TracedSinglePixel` models it, the
        recorded volts minus the offset y₀ divided by ``scale`` (default: ‖A‖, the normalised
        physics' ``scale``; 1 keeps volts). ``records`` picks other records and their order:
        ``"object"``, ``"measurement"``, ``"measurement_v"`` (the volts as recorded) and
        ``"dmd_light_w"`` (the light on each DMD unit, W, in the DMD's order, where the
        object appears rotated by 180°); see ``spibench._torch.MeasurementDataset``."""
        from ._torch import MeasurementDataset

        return MeasurementDataset(self, scheme, ratio, records, scale)


def open_dataset(path: PathLike) -> OpenDataset:
    """Opens a dataset folder made by ``spibench dataset`` (or :func:`make_dataset`)."""
    return OpenDataset(path)
