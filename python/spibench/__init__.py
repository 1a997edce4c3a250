"""spibench from Python: traced DMD single-pixel benches as numpy and scipy objects.

Units follow the library: SI inside (W, A, V, m) and unit-suffixed names (``_mm``, ``_w``,
``_a``, ``_v``). Objects are transmittance maps in [0, 1] on an object kernel's grid, shaped
(H, W) or batched (N, H, W), row 0 at the top. DMD images and unit counts are (down, across),
numpy's order, everywhere (:meth:`Bench.check`, :attr:`Kernel.units`, every per-unit map).

- :class:`Bench` — a bench file: load, set variables, trace, trace an object kernel.
- :class:`Trace` — the traced metrics (k±, b±, k', imbalance, leaks, powers) with standard
  errors, the per-unit maps x_j, g±_j, k±_j, the flux ledger, and paired differences.
- :class:`Kernel` — the object kernel as ``scipy.sparse.csr_matrix`` per detector and state.
- :class:`Acquisition` — one scheme's traced measurement: ``forward`` (simulated, noise off or
  on, bit for bit as ``spibench dataset``), the linear part ``apply`` with its exact
  ``adjoint`` and the ``offset``.
- :func:`reconstruct` — the library's TVAL3 on a measurement.
- :func:`open_dataset`, :func:`make_dataset` — dataset folders of ``spibench dataset``;
  :func:`dataset_array_name` names their arrays.

Errors a user can fix raise :class:`InputError` (a ``ValueError``) with the library's located
message (file, line, field) or the argument's name.
"""

from __future__ import annotations

from . import _spibench
from ._acquisition import Acquisition
from ._bench import Bench
from ._checks import PathLike
from ._dataset import OpenDataset, dataset_array_name, dataset_noise_seed, make_dataset, open_dataset
from ._kernel import Kernel
from ._reconstruct import Reconstruction, reconstruct
from ._spibench import InputError
from ._trace import METRICS, Metric, Trace

__all__ = [
    "InputError",
    "Bench",
    "Trace",
    "Metric",
    "Kernel",
    "Acquisition",
    "Reconstruction",
    "reconstruct",
    "open_dataset",
    "make_dataset",
    "OpenDataset",
    "dataset_noise_seed",
    "dataset_array_name",
    "SCHEMES",
    "METRICS",
    "__version__",
]

__version__ = _spibench.version()

#: The acquisition schemes, as the command line and the dataset manifests name them.
SCHEMES = tuple(_spibench.SCHEMES)
