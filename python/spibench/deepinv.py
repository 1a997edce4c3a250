"""deepinv adapter: a traced spibench acquisition as a ``deepinv.physics.LinearPhysics``.

Optional: importing this module needs ``torch`` and ``deepinv``; the rest of spibench needs
numpy and scipy only.

deepinv's physics are linear, y = N(A x). spibench's measurement is affine,
y_V = A x + y₀ (V) plus the bench's noise, so the adapter works with the offset removed:

- ``physics.A(x)`` is the traced linear part A (``Acquisition.apply``) and ``A_adjoint`` its
  exact adjoint (``Acquisition.adjoint``), on CPU float tensors of shape (B, 1, H, W) and
  (B, M), computed by the library in float64 and returned in the input's dtype; autograd
  goes through the adjoint, so unrolled networks train through them;
- ``physics(x)`` (``forward``) gives measurements with the offset removed, y = y_V − y₀: with
  ``noise="bench"`` (the default) the bench's own simulated measurement (detector, oscilloscope,
  drift and noise: ``Acquisition.forward(noise=True)``) minus y₀; with a deepinv noise model,
  that model applied to A x;
- ``physics.remove_offset(y_v)`` turns recorded volts (a dataset's ``meas_…`` arrays) into
  what ``A`` models, and ``physics.offset`` is y₀ as a tensor.
"""

from __future__ import annotations

from typing import Optional, Union

import numpy as np
import torch
from deepinv.physics import LinearPhysics

from . import Acquisition, InputError

__all__ = ["TracedSinglePixel"]


def _to_numpy(t: torch.Tensor, name: str) -> np.ndarray:
    if not isinstance(t, torch.Tensor):
        raise InputError(f"argument `{name}`: a torch.Tensor is needed, got {type(t).__name__}")
    if t.is_complex():
        raise InputError(f"argument `{name}`: complex tensors are not supported")
    return t.detach().to("cpu", torch.float64).contiguous().numpy()


class _Apply(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x, acq, threads):
        ctx.acq, ctx.threads = acq, threads
        b = x.shape[0]
        y = acq.apply(_to_numpy(x, "x").reshape((b,) + acq.grid), threads=threads)
        return torch.from_numpy(np.asarray(y).reshape(b, -1)).to(x.dtype)

    @staticmethod
    def backward(ctx, g):
        x = ctx.acq.adjoint(_to_numpy(g, "y"), threads=ctx.threads)
        return torch.from_numpy(np.asarray(x)).to(g.dtype).unsqueeze(1), None, None


class _Adjoint(torch.autograd.Function):
    @staticmethod
    def forward(ctx, y, acq, threads):
        ctx.acq, ctx.threads = acq, threads
        x = acq.adjoint(_to_numpy(y, "y").reshape(y.shape[0], -1), threads=threads)
        return torch.from_numpy(np.asarray(x)).to(y.dtype).unsqueeze(1)

    @staticmethod
    def backward(ctx, g):
        b = g.shape[0]
        y = ctx.acq.apply(_to_numpy(g, "x").reshape((b,) + ctx.acq.grid), threads=ctx.threads)
        return torch.from_numpy(np.asarray(y).reshape(b, -1)).to(g.dtype), None, None


class TracedSinglePixel(LinearPhysics):
    """The traced single-pixel acquisition ``acquisition`` as deepinv physics (module
    documentation). Images are (B, 1, H, W) on the kernel grid (transmittance); measurements
    (B, M) in volts with the offset removed (the calibrated scheme: dimensionless).

    :param Acquisition acquisition: the spibench acquisition (scheme, ratio, kernel).
    :param noise: ``"bench"`` (the bench's simulated electronics and noise), ``None`` (none),
        or a deepinv noise model applied to ``A x``.
    :param int seed: record seed of the bench noise; each call draws the next seeds.
    :param int threads: library threads (default: all cores).
    """

    def __init__(
        self,
        acquisition: Acquisition,
        noise: Union[str, None, torch.nn.Module] = "bench",
        seed: int = 0,
        threads: Optional[int] = None,
        **kwargs,
    ):
        if not isinstance(acquisition, Acquisition):
            raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
        h, w = acquisition.grid
        model = noise if isinstance(noise, torch.nn.Module) else None
        if model is None and noise not in ("bench", None):
            raise InputError(f"argument `noise`: \"bench\", None or a deepinv noise model, got {noise!r}")
        extra = {"noise_model": model} if model is not None else {}
        super().__init__(img_size=(1, h, w), **extra, **kwargs)
        self.acquisition = acquisition
        self.bench_noise = noise == "bench"
        self.threads = threads
        self._seed = int(seed)
        self.offset = torch.from_numpy(np.asarray(acquisition.offset, dtype=np.float64))

    def _check_x(self, x: torch.Tensor) -> torch.Tensor:
        h, w = self.acquisition.grid
        if x.ndim != 4 or tuple(x.shape[1:]) != (1, h, w):
            raise InputError(f"argument `x`: shape {tuple(x.shape)}, expected (B, 1, {h}, {w})")
        return x

    def A(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """A x: (B, 1, H, W) → (B, M)."""
        return _Apply.apply(self._check_x(x), self.acquisition, self.threads)

    def A_adjoint(self, y: torch.Tensor, **kwargs) -> torch.Tensor:
        """Aᵀ y: (B, M) → (B, 1, H, W)."""
        m = self.acquisition.measurements
        if y.ndim != 2 or y.shape[1] != m:
            raise InputError(f"argument `y`: shape {tuple(y.shape)}, expected (B, {m})")
        return _Adjoint.apply(y, self.acquisition, self.threads)

    def simulate(self, x: torch.Tensor, seed: Optional[int] = None) -> torch.Tensor:
        """The bench's simulated measurement in volts, offset included (noise on)."""
        self._check_x(x)
        if seed is None:
            seed, self._seed = self._seed, self._seed + 1
        y = self.acquisition.forward(_to_numpy(x, "x")[:, 0], noise=True, seed=int(seed),
                                     threads=self.threads)
        return torch.from_numpy(np.asarray(y).reshape(x.shape[0], -1)).to(x.dtype)

    def remove_offset(self, y_v: torch.Tensor) -> torch.Tensor:
        """Recorded volts → the linear model's measurement, y_v − y₀."""
        return y_v - self.offset.to(y_v.dtype)

    def forward(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """Measurements with the offset removed (module documentation)."""
        if self.bench_noise:
            return self.remove_offset(self.simulate(x))
        return super().forward(x, **kwargs)
