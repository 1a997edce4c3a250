"""Benches: a bench file loaded or built in, its variables, its trace and its object kernel."""

from __future__ import annotations

import os
from typing import Dict, List, Mapping, Optional, Tuple, Union

import numpy as np

from . import _spibench
from ._checks import PathLike, _floats, _threads, _u64
from ._kernel import Kernel
from ._spibench import InputError
from ._trace import Trace


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
        """The file the bench was read from (or the name it was parsed under)."""
        return str(self._b.path())

    def to_ron(self) -> str:
        """The bench as canonical RON text."""
        return self._b.to_ron()

    def check(self) -> Tuple[int, int]:
        """Builds the bench and its electronics (raising :class:`InputError` on a fault);
        returns the DMD units (down, across), numpy's order, as :attr:`Kernel.units`."""
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
        dataset`` traces it (its spec writes grid_px and field_mm as (across, down)), with the
        same bounds: sides of 1 to 1024 pixels, fields up to 1000 mm, at least 2048 rays."""
        try:
            h, w = (int(grid[0]), int(grid[1]))
        except (TypeError, ValueError, IndexError):
            raise InputError("argument `grid`: (H, W) pixels are needed") from None
        if h < 0 or w < 0:
            raise InputError(f"argument `grid`: {grid} is not a number of pixels")
        if np.ndim(field_mm) == 0:
            field_mm = (field_mm, field_mm)
        # The sizes' bounds are the library's (those of a dataset spec's `kernel:` section).
        f = _floats(field_mm, "field_mm", finite=False)
        if f.shape != (2,):
            raise InputError(f"argument `field_mm`: two lengths are needed, got {field_mm}")
        return Kernel(
            self._b.kernel(
                (h, w), (float(f[0]), float(f[1])), _u64(rays, "rays"), _u64(seed, "seed"),
                chart, _threads(threads),
            )
        )

    def __repr__(self) -> str:
        return f"Bench({self.path!r}, edits={self.edits})"


