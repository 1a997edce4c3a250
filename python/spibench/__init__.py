"""spibench from Python: traced DMD single-pixel benches as numpy and scipy objects.

Units follow the library: SI inside (W, A, V, m) and unit-suffixed names (``_mm``, ``_w``,
``_a``, ``_v``). Objects are transmittance maps in [0, 1] on an object kernel's grid, shaped
(H, W) or batched (N, H, W), row 0 at the top. DMD images are (down, across) units.

- :class:`Bench` — a bench file: load, set variables, trace, trace an object kernel.
- :class:`Trace` — the traced metrics (k±, b±, k', imbalance, leaks, powers) with standard
  errors, the per-unit maps x_j, g±_j, k±_j, the flux ledger, and paired differences.
- :class:`Kernel` — the object kernel as ``scipy.sparse.csr_matrix`` per detector and state.
- :class:`Acquisition` — one scheme's traced measurement: ``forward`` (simulated, noise off or
  on, bit for bit as ``spibench dataset``), the linear part ``apply`` with its exact
  ``adjoint`` and the ``offset``.
- :func:`reconstruct` — the library's TVAL3 on a measurement.
- :func:`open_dataset`, :func:`make_dataset` — dataset folders of ``spibench dataset``.

Errors a user can fix raise :class:`InputError` (a ``ValueError``) with the library's located
message (file, line, field) or the argument's name.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Dict, Iterable, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import scipy.sparse as sp

from . import _manifest, _spibench
from ._spibench import InputError

__all__ = [
    "InputError",
    "Bench",
    "Trace",
    "Kernel",
    "Acquisition",
    "Reconstruction",
    "reconstruct",
    "open_dataset",
    "make_dataset",
    "OpenDataset",
    "dataset_noise_seed",
    "SCHEMES",
    "METRICS",
    "__version__",
]

__version__ = _spibench.version()

#: The acquisition schemes, as the command line names them.
SCHEMES = _manifest.SCHEMES

#: The metrics every trace records (name, unit).
METRICS = (
    ("k_plus", "A/W"),
    ("k_minus", "A/W"),
    ("k_prime", "A/W"),
    ("imbalance", "1"),
    ("b_plus", "A"),
    ("b_minus", "A"),
    ("b_minus_minus_b_plus", "A"),
    ("power_plus_w", "W"),
    ("power_minus_w", "W"),
    ("leak_plus", "1"),
    ("leak_minus", "1"),
    ("x_total_w", "W"),
)

PathLike = Union[str, "os.PathLike[str]"]


def dataset_noise_seed(seed: int, s: int) -> int:
    """The record seed (noise and drift) of sample ``s`` of a dataset whose spec seed is ``seed``."""
    return _spibench.dataset_noise_seed(_u64(seed, "seed"), _u64(s, "s"))


# ----------------------------------------------------------------------------------------------
# argument checks: every array crosses as C-contiguous float64 of a checked shape


def _u64(v, name: str) -> int:
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
        raise InputError(f"argument `{name}`: an integer is needed, got {type(v).__name__}")
    if not 0 <= int(v) < 2**64:
        raise InputError(f"argument `{name}`: {v} is not in [0, 2^64)")
    return int(v)


def _threads(threads) -> Optional[int]:
    if threads is None:
        return None
    t = _u64(threads, "threads")
    if t == 0:
        raise InputError("argument `threads`: at least one thread is needed")
    return t


def _floats(a, name: str, finite: bool = True) -> np.ndarray:
    """``a`` as a C-contiguous float64 array; real floating or integer input only."""
    try:
        arr = np.asarray(a)
    except Exception as e:  # noqa: BLE001 - anything numpy cannot read is the caller's input
        raise InputError(f"argument `{name}`: not an array ({e})") from None
    if arr.dtype == np.bool_ or not (
        np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)
    ):
        raise InputError(
            f"argument `{name}`: dtype {arr.dtype} is not a real number type (use float64)"
        )
    arr = np.asarray(arr, dtype=np.float64, order="C")
    if finite and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise InputError(
            f"argument `{name}`: value at index {tuple(int(i) for i in bad)} is not finite "
            f"({arr[tuple(bad)]})"
        )
    return arr


def _batch(a, name: str, item_shape: Tuple[int, ...]) -> Tuple[np.ndarray, bool]:
    """``a`` of shape item_shape or (N,) + item_shape, as an (N, prod) float64 array, and
    whether it was a single item."""
    arr = _floats(a, name)
    k = len(item_shape)
    if arr.shape == item_shape:
        return arr.reshape(1, -1), True
    if arr.ndim == k + 1 and arr.shape[1:] == item_shape:
        return arr.reshape(arr.shape[0], -1), False
    raise InputError(
        f"argument `{name}`: shape {arr.shape}, expected {item_shape} or (N, {', '.join(map(str, item_shape))})"
    )


# ----------------------------------------------------------------------------------------------
# benches and traces


class Bench:
    """An optical bench (a bench file with its ``electronics`` and ``run`` sections).

    Immutable: :meth:`set` returns a new bench.
    """

    __slots__ = ("_b",)

    def __init__(self, inner: "_spibench.Bench"):
        self._b = inner

    @staticmethod
    def load(path: PathLike) -> "Bench":
        """Reads and checks a bench file (RON)."""
        return Bench(_spibench.Bench.load(os.fspath(path)))

    @staticmethod
    def paper() -> "Bench":
        """The paper's bench, as the command line has it built in."""
        return Bench(_spibench.Bench.paper())

    @staticmethod
    def parse(text: str, path: PathLike = "<python>") -> "Bench":
        """A bench from RON text; ``path`` names it in errors and resolves relative files."""
        return Bench(_spibench.Bench.parse(str(text), os.fspath(path)))

    def set(self, settings: Mapping[str, float]) -> "Bench":
        """A new bench with variables set by path, e.g.
        ``{"detectors.minus.decenter_mm.x": 0.3}`` (units as in the path's name)."""
        if not isinstance(settings, Mapping):
            raise InputError("argument `settings`: a mapping of variable path to value is needed")
        items = []
        for k, v in settings.items():
            if not isinstance(k, str):
                raise InputError(f"argument `settings`: key {k!r} is not a variable path")
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise InputError(f"variable `{k}`: {v!r} is not a number") from None
            if not np.isfinite(fv):
                raise InputError(f"variable `{k}`: {fv} is not finite")
            items.append((k, fv))
        return Bench(self._b.set(items))

    def get(self, path: str) -> float:
        """The value of a variable (unit as in the path's name)."""
        return self._b.get(path)

    def variables(self) -> List[str]:
        """Every variable path of this bench (``ELEMENT.FIELD[.COMPONENT]``)."""
        return list(self._b.variables())

    @property
    def edits(self) -> Dict[str, float]:
        """The variables set on the loaded file, in order."""
        return dict(self._b.edits())

    @property
    def path(self) -> str:
        return str(self._b.path())

    def to_ron(self) -> str:
        """The bench as canonical RON text."""
        return self._b.to_ron()

    def check(self) -> Tuple[int, int]:
        """Builds the bench and its electronics (raising :class:`InputError` on a fault);
        returns the DMD units (across, down)."""
        return tuple(self._b.check())

    def trace(self, rays: int, seed: int = 1, threads: Optional[int] = None) -> "Trace":
        """Traces ``rays`` lamp rays with ``seed``, as ``spibench sweep`` traces each point."""
        return Trace(self._b.trace(_u64(rays, "rays"), _u64(seed, "seed"), _threads(threads)))

    def kernel(
        self,
        grid: Tuple[int, int],
        field_mm: Union[float, Tuple[float, float]],
        rays: int,
        seed: int = 1,
        chart: Optional[str] = None,
        threads: Optional[int] = None,
    ) -> "Kernel":
        """The object kernel on ``grid`` = (H, W) pixels covering ``field_mm`` = (height_mm,
        width_mm) (a number: square) of the chart, traced with the chart clear, as ``spibench
        dataset`` traces it (its spec writes grid_px and field_mm as (across, down))."""
        try:
            h, w = (int(grid[0]), int(grid[1]))
        except (TypeError, ValueError, IndexError):
            raise InputError("argument `grid`: (H, W) pixels are needed") from None
        if h <= 0 or w <= 0:
            raise InputError(f"argument `grid`: {grid} has no pixels")
        if np.ndim(field_mm) == 0:
            field_mm = (field_mm, field_mm)
        f = _floats(field_mm, "field_mm")
        if f.shape != (2,) or np.any(f <= 0):
            raise InputError(f"argument `field_mm`: two positive lengths are needed, got {field_mm}")
        return Kernel(
            self._b.kernel(
                (h, w), (float(f[0]), float(f[1])), _u64(rays, "rays"), _u64(seed, "seed"),
                chart, _threads(threads),
            )
        )

    def __repr__(self) -> str:
        return f"Bench({self.path!r}, edits={self.edits})"


@dataclass(frozen=True)
class Metric:
    """A traced number with its standard error (unit in :data:`METRICS`)."""

    value: float
    stderr: float


class Trace:
    """A traced bench: metrics with standard errors, per-unit maps and the flux ledger."""

    def __init__(self, inner: "_spibench.Trace"):
        self._t = inner

    @property
    def rays(self) -> int:
        return self._t.rays

    @property
    def seed(self) -> int:
        return self._t.seed

    def values(self, reference: Optional["Trace"] = None) -> Dict[str, float]:
        """The numbers ``spibench sweep`` records for this bench against ``reference`` (traced
        with the same rays and seed: common random numbers): per metric NAME, NAME_stderr,
        NAME_diff, NAME_diff_stderr (paired), then cmrr_db and arrivals."""
        return dict(self._t.values(None if reference is None else reference._t))

    @property
    def metrics(self) -> Dict[str, Metric]:
        """Each metric of :data:`METRICS` with its standard error."""
        v = self.values()
        return {n: Metric(v[n], v[n + "_stderr"]) for n, _ in METRICS if n in v}

    def diff(self, reference: "Trace") -> Dict[str, Metric]:
        """This bench minus ``reference`` per metric, with the paired standard error."""
        v = self.values(reference)
        return {n: Metric(v[n + "_diff"], v[n + "_diff_stderr"]) for n, _ in METRICS if n in v}

    def _map(self, name: str) -> np.ndarray:
        down, across = self._t.units
        return self._t.map(name).reshape(-1, down, across).squeeze(0) if name != "t_a" else (
            self._t.map(name).reshape(2, 2, down, across)
        )

    @property
    def x_w(self) -> np.ndarray:
        """Power incident on each DMD unit x_j (W), (down, across)."""
        return self._map("x_w")

    @property
    def g_a(self) -> np.ndarray:
        """Per-unit gains g±_j (A), (2, down, across): arm + then arm −."""
        return np.stack([self._map("g_plus_a"), self._map("g_minus_a")])

    @property
    def k_a_per_w(self) -> np.ndarray:
        """k±_j = g±_j / x_j (A/W), (2, down, across); 0 where no light reached the unit."""
        return np.stack([self._map("k_plus_a_per_w"), self._map("k_minus_a_per_w")])

    @property
    def k_stderr_a_per_w(self) -> np.ndarray:
        """Standard errors of k±_j (A/W); +inf where unresolved."""
        return np.stack([self._map("k_plus_stderr_a_per_w"), self._map("k_minus_stderr_a_per_w")])

    @property
    def t_a(self) -> np.ndarray:
        """T[d][s][j] (A): diode d's current from light first meeting unit j in state s,
        (2, 2, down, across), index 0 = +, 1 = −."""
        return self._map("t_a")

    @property
    def ledger(self) -> dict:
        """Where the traced power went (W), per mirror-state world."""
        return self._t.ledger()

    def __repr__(self) -> str:
        m = self.metrics
        return f"Trace(rays={self.rays}, seed={self.seed}, k_prime={m['k_prime'].value:.6g} A/W)"


# ----------------------------------------------------------------------------------------------
# object kernels


def _csr(parts) -> sp.csr_matrix:
    data, indices, indptr, shape = parts
    return sp.csr_matrix(
        (data, indices.astype(np.int64), indptr.astype(np.int64)), shape=tuple(shape)
    )


class Kernel:
    """A traced object kernel: how each object pixel's light reaches each DMD unit and diode.

    For an object t (transmittance, (H, W) flattened row-major):

    - ``t_a[d][s] @ t + t0_a[d][s]``: T[d][s][j] (A), the current of diode d (0 = +, 1 = −)
      from light first meeting unit j in mirror state s;
    - ``g_a[d] @ t + g0_a[d]``: the per-unit gains g±_j = T[d][on] − T[d][off] (A);
    - ``x_w @ t + x0_w``: the power on each unit x_j (W);
    - ``c_a[d] @ t + c0_a[d]``: the traced pattern-independent current of diode d (A).

    Matrices are ``scipy.sparse.csr_matrix`` of shape (units, pixels), units row-major
    (down, across). The ``0`` vectors are the object-independent light (never met the chart).
    """

    def __init__(self, inner: "_spibench.Kernel"):
        self._k = inner
        self._cache: dict = {}

    def _get(self, key, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    @property
    def grid(self) -> Tuple[int, int]:
        """(H, W) object pixels."""
        return tuple(self._k.grid)

    @property
    def field_mm(self) -> Tuple[float, float]:
        """(height_mm, width_mm) of the object grid on the chart."""
        return tuple(self._k.field_mm)

    @property
    def units(self) -> Tuple[int, int]:
        """(down, across) DMD units."""
        return tuple(self._k.units)

    @property
    def rays(self) -> int:
        return self._k.rays

    @property
    def seed(self) -> int:
        return self._k.seed

    @property
    def multi_crossing_current_fraction(self) -> float:
        """Share of the chart light's detected current on paths that met the chart twice or
        more (what the kernel neglects)."""
        return self._k.multi_crossing_current_fraction

    @property
    def chart_current_a(self) -> float:
        """The clear chart's detected current (A), summed over both diodes and both mirror-state
        worlds, of every path that met the chart."""
        return self._k.chart_current_a

    @property
    def multi_crossing_current_a(self) -> float:
        """The part of ``chart_current_a`` on paths that met the chart twice or more (A). The
        full product weights such a path by every pixel it met, the linear part by the first
        only: for objects in [0, 1] the two differ by at most this current in all."""
        return self._k.multi_crossing_current_a

    @property
    def t_a(self) -> List[List[sp.csr_matrix]]:
        """T[d][s] per diode d and state s (A per unit transmittance)."""
        return self._get("t", lambda: [
            [_csr(self._k.csr("t", 2 * d + s)) for s in range(2)] for d in range(2)
        ])

    @property
    def t0_a(self) -> np.ndarray:
        """(2, 2, units) object-independent T (A)."""
        return self._get("t0", lambda: np.stack(
            [self._k.vector("t0", b) for b in range(4)]).reshape(2, 2, -1))

    @property
    def g_a(self) -> List[sp.csr_matrix]:
        """Per diode, the gain matrix G± (A per unit transmittance)."""
        return self._get("g", lambda: [_csr(self._k.csr("g", d)) for d in range(2)])

    @property
    def g_stderr_a(self) -> List[sp.csr_matrix]:
        """Per diode, the standard error of each entry of G± (A), same pattern as ``g_a``."""
        return self._get("gse", lambda: [_csr(self._k.csr("g_stderr", d)) for d in range(2)])

    @property
    def g0_a(self) -> np.ndarray:
        """(2, units) object-independent gains (A)."""
        return np.stack([self._k.vector("g0", d) for d in range(2)])

    @property
    def x_w(self) -> sp.csr_matrix:
        """Power on each unit per unit transmittance (W)."""
        return self._get("x", lambda: _csr(self._k.csr("x", 0)))

    @property
    def x0_w(self) -> np.ndarray:
        """(units,) object-independent power on the units (W)."""
        return self._k.vector("x0", 0)

    @property
    def c_a(self) -> np.ndarray:
        """(2, pixels) traced pattern-independent current per pixel (A)."""
        return np.stack([self._k.vector("c", d) for d in range(2)])

    @property
    def c0_a(self) -> np.ndarray:
        """(2,) object-independent pattern-independent current (A)."""
        return np.array([self._k.vector("c0", d)[0] for d in range(2)])

    def dmd_light(self, objects, threads: Optional[int] = None,
                  linear: bool = False) -> np.ndarray:
        """The light on the DMD units x_j (W) of each object (H, W) or (N, H, W), by the
        library's own kernel product: (down, across) or (N, down, across).

        ``linear=True`` gives the product's linear part, which the sparse matrices hold: light
        that meets the chart more than once is then weighted by the first pixel it met only,
        where the full product weights it by every pixel it met (a few tenths of a percent of
        the chart's light on the paper bench; docs/object_kernels.md)."""
        x, single = _batch(objects, "objects", self.grid)
        out, _ = self._k.product(x, _threads(threads), bool(linear))
        out = out.reshape((-1,) + self.units)
        return out[0] if single else out

    def transport_metrics(self, obj) -> Dict[str, Metric]:
        """The transport of one object (H, W) through the kernel: x_total_w, k±, k', imbalance
        and b± with their standard errors (units as :data:`METRICS`)."""
        x, single = _batch(obj, "object", self.grid)
        if not single:
            raise InputError("argument `object`: one object (H, W) is needed")
        return {n: Metric(v, se) for n, v, se in self._k.transport_metrics(x[0])}

    def transport_a(self, objects, threads: Optional[int] = None,
                    linear: bool = False) -> np.ndarray:
        """T[d][s][j] (A) of each object by the library's kernel product: (2, 2, down,
        across) or (N, 2, 2, down, across); ``linear`` as in :meth:`dmd_light`."""
        x, single = _batch(objects, "objects", self.grid)
        _, t = self._k.product(x, _threads(threads), bool(linear))
        t = t.reshape((-1, 2, 2) + self.units)
        return t[0] if single else t

    def __repr__(self) -> str:
        return f"Kernel(grid={self.grid}, units={self.units}, rays={self.rays}, seed={self.seed})"


# ----------------------------------------------------------------------------------------------
# the acquisition operator


class Acquisition:
    """One scheme's traced acquisition of objects on a kernel's grid.

    ``Acquisition(kernel, scheme, ratio)`` measures with the first M = round(ratio·units)
    patterns of the bench's pattern family through the bench's electronics:

    - :meth:`forward` simulates the measurement (V; the calibrated scheme: 1), the frames through
      the detector and oscilloscope with their drift and noise when ``noise=True``; with the same
      object, bench, seeds and scheme it equals ``spibench dataset``'s measurement bit for bit;
    - :meth:`apply` is its linear part A and :meth:`adjoint` the exact adjoint Aᵀ, with
      ``forward(x, noise=False) ≈ apply(x) + offset`` up to the single pole's transient, clipping
      and the oscilloscope window (equal to ~1e-12 for a bench within range). The calibrated
      double-arm scheme divides by the clear object's swings in A (its measurement divides by
      the object's own).

    ``recorded`` names other schemes recorded together (their sequences share the oscilloscope's
    ranges, which matters with noise on); a dataset's acquisition records every scheme of the
    dataset (:meth:`OpenDataset.acquisition`).
    """

    def __init__(
        self,
        kernel: Kernel,
        scheme: str = "secondary_complementary_balancing",
        ratio: float = 0.25,
        record: str = "frames",
        recorded: Optional[Sequence[str]] = None,
        *,
        _inner=None,
    ):
        if _inner is not None:
            self._a = _inner
        else:
            if not isinstance(kernel, Kernel):
                raise InputError("argument `kernel`: a spibench.Kernel is needed")
            r = float(_floats(ratio, "ratio"))
            self._a = _spibench.Acquisition(
                kernel._k, str(scheme), r, str(record),
                None if recorded is None else [str(s) for s in recorded],
            )
        self.kernel_grid: Tuple[int, int] = tuple(self._a.grid)

    @property
    def scheme(self) -> str:
        return self._a.scheme

    @property
    def measurements(self) -> int:
        """M, the number of measurements."""
        return self._a.measurements

    @property
    def shape(self) -> Tuple[int, int]:
        """(M, pixels) of the linear part."""
        return (self._a.measurements, self._a.pixels)

    @property
    def grid(self) -> Tuple[int, int]:
        """(H, W) of the objects."""
        return self.kernel_grid

    @property
    def units(self) -> Tuple[int, int]:
        """(down, across) DMD units."""
        return tuple(self._a.units)

    @property
    def offset(self) -> np.ndarray:
        """y₀ (M,), the measurement of the black object: the affine part (V)."""
        return self._a.offset

    @property
    def coefficients(self) -> np.ndarray:
        """(ka, kb, ks₊, ks₋, kc₊, kc₋) (V/A) of the measurement model y_i = ka·a_i + kb·b_i +
        ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ + const, a_i = P_i·g₊, b_i = P_i·g₋, S_d = Σ g_d, c_d
        the pattern-independent light of diode d (the linear operator's model)."""
        return np.array(self._a.coefficients, dtype=np.float64)

    @property
    def noise_default(self) -> bool:
        """Whether the bench's run settings switch the noise on."""
        return self._a.noise_default

    @property
    def patterns(self) -> np.ndarray:
        """The M base patterns as 0/1 uint8, (M, down, across)."""
        return self._a.patterns().reshape((-1,) + self.units)

    @property
    def patterns_packed(self) -> np.ndarray:
        """The M base patterns bit-packed as ``patterns.npy`` of a dataset: (M, ⌈units/8⌉)
        uint8, most significant bit first."""
        p = self._a.patterns()
        return np.packbits(p.astype(bool), axis=1)

    def forward(self, x, noise: bool = False, seed: Union[int, Sequence[int]] = 0,
                threads: Optional[int] = None, linear: bool = False) -> np.ndarray:
        """Simulated measurements (M,) or (N, M) of objects (H, W) or (N, H, W).

        ``linear=True`` measures through the kernel's linear part (see
        :meth:`Kernel.dmd_light`), which ``apply(x) + offset`` equals; the default is the full
        product, as ``spibench dataset`` measures.

        ``seed``: an int gives object n the record seed ``dataset_noise_seed(seed, n)`` (so the
        objects of samples 0…N−1 of a dataset with seed ``seed`` give its measurements); a
        sequence gives each object its record seed. The seed also keys the drift.
        """
        xb, single = _batch(x, "x", self.grid)
        n = xb.shape[0]
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_)):
            s0 = _u64(seed, "seed")
            seeds = np.array([_spibench.dataset_noise_seed(s0, i) for i in range(n)], dtype=np.uint64)
        else:
            try:
                seeds = np.array([_u64(s, "seed") for s in seed], dtype=np.uint64)
            except TypeError:
                raise InputError("argument `seed`: an int or a sequence of ints is needed") from None
            if seeds.shape != (n,):
                raise InputError(f"argument `seed`: {seeds.size} seeds for {n} objects")
        y = self._a.forward(xb, bool(noise), seeds, _threads(threads), bool(linear))
        return y[0] if single else y

    def apply(self, x, threads: Optional[int] = None) -> np.ndarray:
        """A x, the linear part, (M,) or (N, M)."""
        xb, single = _batch(x, "x", self.grid)
        y = self._a.apply(xb, _threads(threads))
        return y[0] if single else y

    def adjoint(self, y, threads: Optional[int] = None) -> np.ndarray:
        """Aᵀ y, (H, W) or (N, H, W) for y (M,) or (N, M)."""
        yb, single = _batch(y, "y", (self.measurements,))
        x = self._a.adjoint(yb, _threads(threads)).reshape((-1,) + self.grid)
        return x[0] if single else x

    def matrix(self) -> np.ndarray:
        """A as a dense (M, pixels) array (small sizes only)."""
        m, n = self.shape
        if m * n > 50_000_000:
            raise InputError(f"matrix(): {m}×{n} is too large for a dense array")
        return self.adjoint(np.eye(m)).reshape(m, n)

    def as_linear_operator(self):
        """A as a ``scipy.sparse.linalg.LinearOperator`` on flattened objects."""
        from scipy.sparse.linalg import LinearOperator

        m, n = self.shape
        h, w = self.grid
        return LinearOperator(
            (m, n), dtype=np.float64,
            matvec=lambda v: self.apply(np.reshape(v, (h, w))),
            rmatvec=lambda y: self.adjoint(np.ravel(y)).ravel(),
        )

    def __repr__(self) -> str:
        return f"Acquisition({self.scheme}, M={self.measurements}, grid={self.grid}, units={self.units})"


@dataclass(frozen=True)
class Reconstruction:
    """A TVAL3 reconstruction on the DMD units."""

    image: np.ndarray
    """(down, across), on the measurement's scale."""
    iterations: int
    stop: str
    """``Tolerance``, ``MaxOuter`` or ``MaxIterations``."""
    converged: bool
    relative_residual: float
    seconds: float


def reconstruct(y, acquisition: Acquisition, threads: Optional[int] = None) -> Reconstruction:
    """Reconstructs the image on the DMD units from measurements ``y`` (M,) with the library's
    TVAL3, as ``spibench run`` solves the acquisition's scheme (the bench's solver settings)."""
    if not isinstance(acquisition, Acquisition):
        raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
    v = _floats(y, "y")
    if v.shape != (acquisition.measurements,):
        raise InputError(f"argument `y`: shape {v.shape}, expected ({acquisition.measurements},)")
    img, it, stop, conv, res, secs = acquisition._a.reconstruct(v, _threads(threads))
    return Reconstruction(img, it, stop, conv, res, secs)


# ----------------------------------------------------------------------------------------------
# datasets


def make_dataset(spec: PathLike, out: PathLike, threads: Optional[int] = None) -> int:
    """Makes the dataset of ``spec`` in ``out``, as ``spibench dataset SPEC --out OUT``; returns
    the shards written."""
    return _spibench.make_dataset(os.fspath(spec), os.fspath(out), _threads(threads))


class OpenDataset:
    """A dataset folder: the manifest, every array as numpy (memory-mapped, shards
    concatenated lazily by :meth:`array`), and the acquisitions that made it."""

    def __init__(self, path: PathLike):
        self.path = os.fspath(path)
        mpath = os.path.join(self.path, "manifest.json")
        try:
            with open(mpath, encoding="utf-8") as f:
                manifest = json.load(f)
        except FileNotFoundError:
            raise InputError(f"{mpath}: no manifest.json: not a spibench dataset folder") from None
        # Every name and path is checked before any other file of the folder is opened.
        _manifest._error = InputError
        self.manifest = _manifest.checked(manifest, self.path, mpath)
        self.shards = sorted(self.manifest["shards"], key=lambda s: s["index"])
        self._inner = None

    @property
    def names(self) -> List[str]:
        """The array names of every sample (``object``, ``meas_SCHEME_rRATIO``, ``k``, …)."""
        return [a["name"] for a in self.manifest["schema"]]

    @property
    def samples(self) -> int:
        return sum(s["samples"] for s in self.shards)

    @property
    def seed(self) -> int:
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
        return [os.path.join(self.path, s["dir"], f"{name}.npy") for s in self.shards]

    def array(self, name: str, mmap: bool = True) -> np.ndarray:
        """Array ``name`` of every sample, shards concatenated (one shard: a memory map)."""
        if name not in self.names:
            raise InputError(f"argument `name`: no array {name!r}; the dataset has {self.names}")
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
        a = self._rust().acquisition(str(scheme), float(ratio))
        return Acquisition(None, _inner=a)

    def kernel(self) -> Kernel:
        return Kernel(self._rust().kernel())

    def torch_dataset(self, scheme: str, ratio: float):
        """A ``torch.utils.data.Dataset`` of (measurement, dmd_image, object) per sample:
        the measurement y (M,), the light the measurement sees on the DMD units x_j (W, down ×
        across, the kernel product of the object), and the object on the kernel grid."""
        from ._torch import MeasurementDataset

        return MeasurementDataset(self, scheme, ratio)


def open_dataset(path: PathLike) -> OpenDataset:
    """Opens a dataset folder made by ``spibench dataset`` (or :func:`make_dataset`)."""
    return OpenDataset(path)
