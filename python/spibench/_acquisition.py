"""The acquisition operator: one scheme's traced measurement, its linear part and exact
adjoint."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

from . import _spibench
from ._checks import F64, _batch, _floats, _threads, _u64
from ._kernel import Kernel
from ._spibench import InputError


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
    ):
        if not isinstance(kernel, Kernel):
            raise InputError("argument `kernel`: a spibench.Kernel is needed")
        r = float(_floats(ratio, "ratio"))
        self._set(_spibench.Acquisition(
            kernel._k, str(scheme), r, str(record),
            None if recorded is None else [str(s) for s in recorded],
        ))

    @classmethod
    def _of(cls, inner: "_spibench.Acquisition") -> "Acquisition":
        """The acquisition around the extension's ``inner`` (a dataset's)."""
        a = cls.__new__(cls)
        a._set(inner)
        return a

    def _set(self, inner: "_spibench.Acquisition") -> None:
        self._a = inner
        self.kernel_grid: Tuple[int, int] = tuple(inner.grid)
        self._norm: Optional[float] = None

    @property
    def scheme(self) -> str:
        """The scheme's key (``scb``, ``double_arm``, …), as in :data:`spibench.SCHEMES`."""
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
    def offset(self) -> F64:
        """y₀ (M,), the measurement of the black object: the affine part (V)."""
        return self._a.offset

    @property
    def coefficients(self) -> F64:
        """(ka, kb, ks₊, ks₋, kc₊, kc₋) (V/A) of the measurement model y_i = ka·a_i + kb·b_i +
        ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ + const, a_i = P_i·g₊, b_i = P_i·g₋, S_d = Σ g_d, c_d
        the pattern-independent light of diode d (the linear operator's model)."""
        k = self._a.coefficients
        return np.array([k.ka, k.kb, *k.ks, *k.kc], dtype=np.float64)

    @property
    def noise_default(self) -> bool:
        """Whether the bench's run settings switch the noise on."""
        return self._a.noise_default

    @property
    def patterns(self) -> npt.NDArray[np.uint8]:
        """The M base patterns as 0/1 uint8, (M, down, across)."""
        return self._a.patterns().reshape((-1,) + self.units)

    @property
    def patterns_packed(self) -> npt.NDArray[np.uint8]:
        """The M base patterns bit-packed as ``patterns.npy`` of a dataset: (M, ⌈units/8⌉)
        uint8, most significant bit first."""
        p = self._a.patterns()
        return np.packbits(p.astype(bool), axis=1)

    def forward(self, x: npt.ArrayLike, noise: bool = False,
                seed: Union[int, Sequence[int]] = 0, threads: Optional[int] = None,
                linear: bool = False) -> F64:
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

    def apply(self, x: npt.ArrayLike, threads: Optional[int] = None) -> F64:
        """A x, the linear part, (M,) or (N, M)."""
        xb, single = _batch(x, "x", self.grid)
        y = self._a.apply(xb, _threads(threads))
        return y[0] if single else y

    def adjoint(self, y: npt.ArrayLike, threads: Optional[int] = None) -> F64:
        """Aᵀ y, (H, W) or (N, H, W) for y (M,) or (N, M)."""
        yb, single = _batch(y, "y", (self.measurements,))
        x = self._a.adjoint(yb, _threads(threads)).reshape((-1,) + self.grid)
        return x[0] if single else x

    def matrix(self) -> F64:
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

    def operator_norm(self) -> float:
        """‖A‖, the spectral norm of the linear part (its largest singular value, V per unit
        transmittance; the calibrated scheme: per unit transmittance), by ARPACK on
        :meth:`apply` and :meth:`adjoint` from a fixed start, so the same acquisition gives the
        same number; computed once. The normalised deepinv physics divides A by it."""
        if self._norm is None:
            from scipy.sparse.linalg import svds

            op = self.as_linear_operator()
            v0 = np.ones(min(op.shape))
            k = svds(op, k=1, v0=v0, return_singular_vectors=False, tol=1e-12)
            self._norm = float(k[0])
        return self._norm

    def __repr__(self) -> str:
        return f"Acquisition({self.scheme}, M={self.measurements}, grid={self.grid}, units={self.units})"


