"""The traced acquisition's linear part as a torch module, on any device (needs torch).

:class:`TracedLinear` is y = A t of :meth:`spibench.Acquisition.apply` in torch tensor
operations, with its exact adjoint Aᵀ (:meth:`spibench.Acquisition.adjoint`). The operator the
library forms term by term (``Acquisition.coefficients``),

    y_i = ka·P_i·G₊t + kb·P_i·G₋t + ks₊·Σ_j (G₊t)_j + ks₋·Σ_j (G₋t)_j + kc₊·c₊·t + kc₋·c₋·t,

is folded once, in float64, into one sparse kernel matrix and one row:

    A t = P (G t) + (r·t) 1,   G = ka·G₊ + kb·G₋,   r = ks₊·1ᵀG₊ + ks₋·1ᵀG₋ + kc₊·c₊ + kc₋·c₋,
    Aᵀ y = Gᵀ (Pᵀ y) + (1ᵀy) r,

with P the M base patterns (0/1) on the DMD units. G is held as a CSR matrix (its three
arrays, and those of Gᵀ, as buffers) or, with ``kernel_format="dense"``, as a dense matrix;
P bit-packed, one bit per entry: the buffer ``patterns`` is uint8 (M, ⌈units/8⌉), each row
most significant bit first and padded with zero bits to whole bytes (``numpy.packbits(P,
axis=1)``, as :attr:`spibench.Acquisition.patterns_packed` and a dataset's ``patterns.npy``),
unpacked on the module's device into its dtype in blocks of rows at each call (a bit table
looked up by byte; exact); the offset y₀ as a buffer. So ``.to(device)``, ``.double()`` and
``state_dict`` carry everything, and autograd goes through the exact adjoint (a
``torch.autograd.Function`` whose backward is the other direction).

Without the kernel (``kernel=None``) the module holds A as a dense (M, pixels) matrix, read
from the acquisition's own adjoint (``Acquisition.matrix``; small sizes only).

Shapes follow spyrit's ``Linear`` convention: objects (*, H, W) → measurements (*, M), and
the adjoint (*, M) → (*, H, W). Outputs are on the input's device and in its dtype, which must
be the module's (float32 by default; ``dtype=torch.float64`` on request, or ``.double()``).
"""

from __future__ import annotations

import warnings
from typing import Optional

import numpy as np
import torch

from ._acquisition import Acquisition
from ._kernel import Kernel
from ._spibench import InputError

__all__ = ["TracedLinear"]

#: Pattern entries unpacked into floats at a time (rows of P per block × units).
_BLOCK_ENTRIES = 1 << 22


def _pack_patterns(acquisition: Acquisition) -> torch.Tensor:
    """The M base patterns bit-packed, (M, ⌈units/8⌉) uint8: ``numpy.packbits(P, axis=1)``,
    most significant bit first, each row padded with zero bits to whole bytes."""
    return torch.from_numpy(np.ascontiguousarray(acquisition.patterns_packed, dtype=np.uint8))


def _bit_table(dtype: torch.dtype, device: torch.device) -> torch.Tensor:
    """(256, 8): row b the bits of byte b, most significant first, as 0/1 in ``dtype`` on
    ``device`` (shift and mask; 8 KiB at most, made at each call)."""
    shifts = torch.arange(7, -1, -1, device=device)
    return ((torch.arange(256, device=device).unsqueeze(1) >> shifts) & 1).to(dtype)


def _unpack(packed: torch.Tensor, units: int, dtype: torch.dtype) -> torch.Tensor:
    """Rows of packed patterns (rows, ⌈units/8⌉) as 0/1 (rows, units) in ``dtype``, on their
    device: each byte looked up in the bit table, the padding bits dropped."""
    bits = torch.nn.functional.embedding(packed.int(), _bit_table(dtype, packed.device))
    return bits.reshape(packed.shape[0], -1)[:, :units]


def _block_rows(units: int) -> int:
    """Rows of P unpacked at a time."""
    return max(1, _BLOCK_ENTRIES // max(1, units))


def _patterns_apply(packed: torch.Tensor, units: int, v: torch.Tensor) -> torch.Tensor:
    """v Pᵀ for v (N, units) and P packed (M, ⌈units/8⌉): (N, M), P unpacked in blocks of
    rows (plain torch operations: autograd goes through v, its backward the products of
    :func:`_patterns_adjoint`)."""
    rows = _block_rows(units)
    m = packed.shape[0]
    if rows >= m:
        return v @ _unpack(packed, units, v.dtype).T
    return torch.cat([v @ _unpack(packed[i:i + rows], units, v.dtype).T
                      for i in range(0, m, rows)], dim=1)


def _patterns_adjoint(packed: torch.Tensor, units: int, y: torch.Tensor) -> torch.Tensor:
    """y P for y (N, M) and P packed (M, ⌈units/8⌉): (N, units), P unpacked in blocks of
    rows."""
    rows = _block_rows(units)
    out = None
    for i in range(0, packed.shape[0], rows):
        part = y[:, i:i + rows] @ _unpack(packed[i:i + rows], units, y.dtype)
        out = part if out is None else out + part
    if out is None:
        return y.new_zeros((y.shape[0], units))
    return out


class _Linear(torch.autograd.Function):
    """y = A x on flattened objects (N, pixels); backward Aᵀ (the module's exact adjoint)."""

    @staticmethod
    def forward(ctx, x, op):
        ctx.op = op
        return op._a(x)

    @staticmethod
    def backward(ctx, g):
        return ctx.op._at(g), None


class _Adjoint(torch.autograd.Function):
    """x = Aᵀ y on measurements (N, M); backward A."""

    @staticmethod
    def forward(ctx, y, op):
        ctx.op = op
        return op._at(y)

    @staticmethod
    def backward(ctx, g):
        return ctx.op._a(g), None


def _folded(acquisition: Acquisition, kernel: Kernel):
    """G = ka·G₊ + kb·G₋ (scipy CSR, units × pixels) and r (pixels,), in float64."""
    ka, kb, ks_p, ks_m, kc_p, kc_m = (float(v) for v in acquisition.coefficients)
    gp, gm = kernel.g_a
    g = (ka * gp + kb * gm).tocsr()
    g.sort_indices()
    c = kernel.c_a
    r = (ks_p * np.asarray(gp.sum(axis=0)).ravel() + ks_m * np.asarray(gm.sum(axis=0)).ravel()
         + kc_p * c[0] + kc_m * c[1])
    return g, r


class TracedLinear(torch.nn.Module):
    """The linear part A of a traced acquisition as a ``torch.nn.Module`` (module
    documentation): ``op(x)`` maps objects (*, H, W) to measurements (*, M), ``op.adjoint(y)``
    maps (*, M) to (*, H, W); ``op.offset`` is y₀ (M,), so that ``op(x) + op.offset`` is the
    noise-free measurement in volts (the calibrated scheme: dimensionless). With a kernel, the
    patterns are held bit-packed: the buffer ``patterns`` is uint8 (M, ⌈units/8⌉) as
    :attr:`spibench.Acquisition.patterns_packed` gives it (an eighth of one byte per entry),
    unpacked in blocks on the module's device at each call.

    :param Acquisition acquisition: the scheme, ratio and patterns.
    :param Kernel kernel: the object kernel the acquisition was built from (its matrices G± and
        c± are read); ``None`` holds A dense, from the acquisition alone (small sizes).
    :param dtype: ``torch.float32`` (default) or ``torch.float64``.
    :param device: where the buffers go (default: CPU).
    :param str kernel_format: ``"csr"`` (default) or ``"dense"``, how G is held.
    """

    def __init__(
        self,
        acquisition: Acquisition,
        kernel: Optional[Kernel] = None,
        dtype: torch.dtype = torch.float32,
        device=None,
        kernel_format: str = "csr",
    ):
        super().__init__()
        if not isinstance(acquisition, Acquisition):
            raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
        if dtype not in (torch.float32, torch.float64):
            raise InputError(f"argument `dtype`: torch.float32 or torch.float64, got {dtype}")
        if kernel_format not in ("csr", "dense"):
            raise InputError(f"argument `kernel_format`: \"csr\" or \"dense\", got {kernel_format!r}")
        self.grid = tuple(acquisition.grid)
        self.measurements = int(acquisition.measurements)
        self.pixels = self.grid[0] * self.grid[1]
        f64 = dict(dtype=torch.float64)
        self.register_buffer("offset", torch.tensor(np.asarray(acquisition.offset), **f64))
        if kernel is None:
            self.form = "matrix"
            self.register_buffer("matrix", torch.from_numpy(acquisition.matrix().copy()))
        else:
            self._set_kernel(acquisition, kernel, kernel_format)
        self.to(device=device, dtype=dtype)

    def _set_kernel(self, acquisition: Acquisition, kernel: Kernel, kernel_format: str) -> None:
        """The folded kernel G, the row r and the patterns P as buffers."""
        if not isinstance(kernel, Kernel):
            raise InputError("argument `kernel`: a spibench.Kernel is needed")
        if kernel.grid != self.grid or kernel.units != acquisition.units:
            raise InputError(
                f"argument `kernel`: grid {kernel.grid} and units {kernel.units}, the "
                f"acquisition has grid {self.grid} and units {acquisition.units}")
        g, r = _folded(acquisition, kernel)
        self.form = kernel_format
        self.units = int(g.shape[0])
        if kernel_format == "dense":
            self.register_buffer("g", torch.from_numpy(g.toarray()))
        else:
            gt = g.T.tocsr()
            gt.sort_indices()
            for name, m in (("g", g), ("gt", gt)):
                self.register_buffer(name + "_crow", torch.from_numpy(m.indptr.astype(np.int64)))
                self.register_buffer(name + "_col", torch.from_numpy(m.indices.astype(np.int64)))
                self.register_buffer(name + "_values", torch.from_numpy(m.data.astype(np.float64)))
        self.register_buffer("r", torch.from_numpy(np.ascontiguousarray(r, dtype=np.float64)))
        self.register_buffer("patterns", _pack_patterns(acquisition))
        self._check_against(acquisition)

    def _check_against(self, acquisition: Acquisition) -> None:
        """Refuses a kernel that is not the acquisition's: A of one object against the
        library's."""
        t = np.random.default_rng(0).random(self.grid)
        want = np.asarray(acquisition.apply(t))
        got = self._a(torch.from_numpy(t.reshape(1, -1))).numpy()[0]
        err = np.linalg.norm(got - want) / max(np.linalg.norm(want), 1e-300)
        if not err < 1e-9:
            raise InputError(f"argument `kernel`: not the acquisition's kernel (A differs by "
                             f"{err:.2e} relative)")

    def _csr(self, name: str, rows: int, cols: int) -> torch.Tensor:
        """The CSR matrix ``name`` (rows × cols) over its three buffers (no copy)."""
        with warnings.catch_warnings():
            # torch flags its sparse CSR layout as beta at each construction.
            warnings.simplefilter("ignore", UserWarning)
            return torch.sparse_csr_tensor(
                getattr(self, name + "_crow"), getattr(self, name + "_col"),
                getattr(self, name + "_values"), (rows, cols), check_invariants=False)

    def _patterns_apply(self, v: torch.Tensor) -> torch.Tensor:
        """v Pᵀ for v (N, units): (N, M)."""
        return _patterns_apply(self.patterns, self.units, v)

    def _patterns_adjoint(self, y: torch.Tensor) -> torch.Tensor:
        """y P for y (N, M): (N, units)."""
        return _patterns_adjoint(self.patterns, self.units, y)

    def _a(self, x: torch.Tensor) -> torch.Tensor:
        """A x for x (N, pixels) → (N, M), no autograd."""
        if self.form == "matrix":
            return x @ self.matrix.T
        if self.form == "dense":
            u = self.g @ x.T
        else:
            u = self._csr("g", self.units, self.pixels) @ x.T.contiguous()
        return self._patterns_apply(u.T) + (x @ self.r)[:, None]

    def _at(self, y: torch.Tensor) -> torch.Tensor:
        """Aᵀ y for y (N, M) → (N, pixels), no autograd."""
        if self.form == "matrix":
            return y @ self.matrix
        v = self._patterns_adjoint(y)
        if self.form == "dense":
            t = v @ self.g
        else:
            t = (self._csr("gt", self.pixels, self.units) @ v.T.contiguous()).T
        return t + y.sum(dim=1, keepdim=True) * self.r

    def _check(self, v: torch.Tensor, name: str, tail: tuple) -> None:
        if not isinstance(v, torch.Tensor):
            raise InputError(f"argument `{name}`: a torch.Tensor is needed, got {type(v).__name__}")
        if tuple(v.shape[v.ndim - len(tail):]) != tail or v.ndim < len(tail):
            raise InputError(f"argument `{name}`: shape {tuple(v.shape)}, expected (*, "
                             f"{', '.join(str(n) for n in tail)})")
        own = self.offset
        if v.dtype != own.dtype or v.device != own.device:
            raise InputError(f"argument `{name}`: {v.dtype} on {v.device}, the operator is "
                             f"{own.dtype} on {own.device} (use .to())")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """A x: objects (*, H, W) → measurements (*, M) (the offset not added)."""
        self._check(x, "x", self.grid)
        lead = x.shape[:-2]
        y = _Linear.apply(x.reshape(-1, self.pixels), self)
        return y.reshape(lead + (self.measurements,))

    def adjoint(self, y: torch.Tensor) -> torch.Tensor:
        """Aᵀ y: measurements (*, M) → objects (*, H, W)."""
        self._check(y, "y", (self.measurements,))
        lead = y.shape[:-1]
        x = _Adjoint.apply(y.reshape(-1, self.measurements), self)
        return x.reshape(lead + self.grid)

    def extra_repr(self) -> str:
        """The grid, M, the kernel's form and the dtype, for ``repr``."""
        return (f"grid={self.grid}, measurements={self.measurements}, form={self.form}, "
                f"dtype={self.offset.dtype}")
