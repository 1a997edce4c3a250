"""Object kernels: how each object pixel's light reaches each DMD unit and diode, as scipy
sparse matrices and as the library's own product."""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from . import _spibench
from ._checks import F64, _batch, _threads
from ._spibench import InputError, MirrorState
from ._trace import ARMS, Metric

#: The mirror states in index order (0 = +, 1 = −), as the state axis of T.
STATES = (MirrorState.Plus, MirrorState.Minus)


def _csr(m: "_spibench.Csr") -> sp.csr_matrix:
    return sp.csr_matrix(
        (m.data, m.indices.astype(np.int64), m.indptr.astype(np.int64)), shape=tuple(m.shape)
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
        """Lamp rays traced for the kernel."""
        return self._k.rays

    @property
    def seed(self) -> int:
        """Seed of the kernel trace."""
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
        return self._get("t", lambda: [[_csr(self._k.t(d, s)) for s in STATES] for d in ARMS])

    @property
    def t0_a(self) -> F64:
        """(2, 2, units) object-independent T (A)."""
        return self._get("t0", lambda: np.stack(
            [np.stack([self._k.t0(d, s) for s in STATES]) for d in ARMS]))

    @property
    def g_a(self) -> List[sp.csr_matrix]:
        """Per diode, the gain matrix G± (A per unit transmittance)."""
        return self._get("g", lambda: [_csr(self._k.g(d)) for d in ARMS])

    @property
    def g_stderr_a(self) -> List[sp.csr_matrix]:
        """Per diode, the standard error of each entry of G± (A), same pattern as ``g_a``."""
        return self._get("gse", lambda: [_csr(self._k.g_stderr(d)) for d in ARMS])

    @property
    def g0_a(self) -> F64:
        """(2, units) object-independent gains (A)."""
        return np.stack([self._k.g0(d) for d in ARMS])

    @property
    def x_w(self) -> sp.csr_matrix:
        """Power on each unit per unit transmittance (W)."""
        return self._get("x", lambda: _csr(self._k.x()))

    @property
    def x0_w(self) -> F64:
        """(units,) object-independent power on the units (W)."""
        return self._k.x0()

    @property
    def c_a(self) -> F64:
        """(2, pixels) traced pattern-independent current per pixel (A)."""
        return np.stack([self._k.c(d) for d in ARMS])

    @property
    def c0_a(self) -> F64:
        """(2,) object-independent pattern-independent current (A)."""
        return np.array([self._k.c0(d) for d in ARMS])

    def dmd_light(self, objects: npt.ArrayLike, threads: Optional[int] = None,
                  linear: bool = False) -> F64:
        """The light on the DMD units x_j (W) of each object (H, W) or (N, H, W), by the
        library's own kernel product: (down, across) or (N, down, across).

        ``linear=True`` gives the product's linear part, which the sparse matrices hold: light
        that meets the chart more than once is then weighted by the first pixel it met only,
        where the full product weights it by every pixel it met (a few tenths of a percent of
        the chart's light on the paper bench; docs/object_kernels.md)."""
        x, single = _batch(objects, "objects", self.grid)
        out = self._k.product(x, _threads(threads), bool(linear)).x_w
        out = out.reshape((-1,) + self.units)
        return out[0] if single else out

    def transport_metrics(self, obj: npt.ArrayLike) -> Dict[str, Metric]:
        """The transport of one object (H, W) through the kernel: x_total_w, k±, k', imbalance
        and b± with their standard errors (units as :data:`METRICS`)."""
        x, single = _batch(obj, "object", self.grid)
        if not single:
            raise InputError("argument `object`: one object (H, W) is needed")
        return {n: Metric(e.value, e.stderr) for n, e in self._k.transport_metrics(x[0])}

    def transport_a(self, objects: npt.ArrayLike, threads: Optional[int] = None,
                    linear: bool = False) -> F64:
        """T[d][s][j] (A) of each object by the library's kernel product: (2, 2, down,
        across) or (N, 2, 2, down, across); ``linear`` as in :meth:`dmd_light`."""
        x, single = _batch(objects, "objects", self.grid)
        t = self._k.product(x, _threads(threads), bool(linear)).t_a
        t = t.reshape((-1, 2, 2) + self.units)
        return t[0] if single else t

    def __repr__(self) -> str:
        return f"Kernel(grid={self.grid}, units={self.units}, rays={self.rays}, seed={self.seed})"


