"""The library's TVAL3 on a measurement."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy.typing as npt

from ._acquisition import Acquisition
from ._checks import F64, _floats, _threads
from ._spibench import InputError


@dataclass(frozen=True)
class Reconstruction:
    """A TVAL3 reconstruction on the DMD units."""

    image: F64
    """(down, across), on the measurement's scale."""
    iterations: int
    stop: str
    """``Tolerance``, ``MaxOuter`` or ``MaxIterations``."""
    converged: bool
    relative_residual: float
    seconds: float


def reconstruct(y: npt.ArrayLike, acquisition: Acquisition,
                threads: Optional[int] = None) -> Reconstruction:
    """Reconstructs the image on the DMD units from measurements ``y`` (M,) with the library's
    TVAL3, as ``spibench run`` solves the acquisition's scheme (the bench's solver settings)."""
    if not isinstance(acquisition, Acquisition):
        raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
    v = _floats(y, "y")
    if v.shape != (acquisition.measurements,):
        raise InputError(f"argument `y`: shape {v.shape}, expected ({acquisition.measurements},)")
    s = acquisition._a.reconstruct(v, _threads(threads))
    return Reconstruction(s.image, s.iterations, s.stop, s.converged, s.relative_residual,
                          s.seconds)
