"""Argument checks shared by the classes: every array crosses into the extension as
C-contiguous float64 of a checked shape, every count as an unsigned 64-bit integer."""

from __future__ import annotations

import os
from typing import Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._spibench import InputError

#: A path argument.
PathLike = Union[str, "os.PathLike[str]"]
#: A float64 array, as every array result is.
F64 = npt.NDArray[np.float64]


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


def _floats(a: npt.ArrayLike, name: str, finite: bool = True) -> F64:
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


def _batch(a: npt.ArrayLike, name: str, item_shape: Tuple[int, ...]) -> Tuple[F64, bool]:
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
