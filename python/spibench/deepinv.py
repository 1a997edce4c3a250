"""deepinv adapter: a traced spibench acquisition as a ``deepinv.physics.LinearPhysics``.

Optional: importing this module needs ``torch`` and ``deepinv``; the rest of spibench needs
numpy and scipy only.

deepinv's physics are linear, y = N(A x). spibench's measurement is affine,
y_V = A x + y₀ (V) plus the bench's noise, so the adapter works with the offset removed:

- ``physics.A(x)`` is the traced linear part A and ``A_adjoint`` its exact adjoint, on tensors
  of shape (B, 1, H, W) and (B, M), computed by torch on the module's device and in its dtype
  (:class:`spibench.nn.TracedLinear`, float32 by default; ``.double()``, ``.to(device)``);
  autograd goes through the adjoint, so unrolled networks train through them;
- ``physics(x)`` (``forward``) gives measurements with the offset removed, y = y_V − y₀: with
  ``noise="bench"`` (the default) the bench's own simulated measurement (detector, oscilloscope,
  drift and noise: ``Acquisition.forward(noise=True)``, computed by the library on the host and
  returned on the input's device) minus y₀; with a deepinv noise model, that model applied to
  A x;
- ``physics.remove_offset(y_v)`` turns recorded volts (a dataset's ``meas_…`` arrays) into
  what ``A`` models, and ``physics.offset`` is y₀ as a tensor (a buffer of the operator).
"""

from __future__ import annotations

from typing import Optional, Union

import numpy as np
import torch
from deepinv.physics import LinearPhysics

from . import Acquisition, InputError, Kernel
from .nn import TracedLinear

__all__ = ["TracedSinglePixel"]


def _to_numpy(t: torch.Tensor, name: str) -> np.ndarray:
    """``t`` as a float64 numpy array on the host (the bench simulation's input)."""
    if not isinstance(t, torch.Tensor):
        raise InputError(f"argument `{name}`: a torch.Tensor is needed, got {type(t).__name__}")
    if t.is_complex():
        raise InputError(f"argument `{name}`: complex tensors are not supported")
    return t.detach().to("cpu", torch.float64).contiguous().numpy()


class TracedSinglePixel(LinearPhysics):
    """The traced single-pixel acquisition ``acquisition`` as deepinv physics (module
    documentation). Images are (B, 1, H, W) on the kernel grid (transmittance); measurements
    (B, M) in volts with the offset removed (the calibrated scheme: dimensionless).

    :param Acquisition acquisition: the spibench acquisition (scheme, ratio, kernel).
    :param noise: ``"bench"`` (the bench's simulated electronics and noise), ``None`` (none),
        or a deepinv noise model applied to ``A x``.
    :param int seed: record seed of the bench noise; each call draws the next seeds.
    :param int threads: library threads of the bench simulation (default: all cores).
    :param Kernel kernel: the acquisition's object kernel: A is then held as its sparse
        matrices (:class:`spibench.nn.TracedLinear`); without it, as a dense matrix read from
        the acquisition (small sizes only).
    :param dtype: ``torch.float32`` (default) or ``torch.float64``.
    :param device: where the operator's buffers go (default: CPU).
    """

    def __init__(
        self,
        acquisition: Acquisition,
        noise: Union[str, None, torch.nn.Module] = "bench",
        seed: int = 0,
        threads: Optional[int] = None,
        kernel: Optional[Kernel] = None,
        dtype: torch.dtype = torch.float32,
        device=None,
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
        self.operator = TracedLinear(acquisition, kernel, dtype=dtype, device=device)
        self.bench_noise = noise == "bench"
        self.threads = threads
        self._seed = int(seed)

    @property
    def offset(self) -> torch.Tensor:
        """y₀ (M,), the measurement of the black object, on the operator's device and dtype."""
        return self.operator.offset

    def _check_x(self, x: torch.Tensor) -> torch.Tensor:
        """``x`` itself, refused unless a (B, 1, H, W) tensor on the kernel grid."""
        h, w = self.acquisition.grid
        if not isinstance(x, torch.Tensor):
            raise InputError(f"argument `x`: a torch.Tensor is needed, got {type(x).__name__}")
        if x.ndim != 4 or tuple(x.shape[1:]) != (1, h, w):
            raise InputError(f"argument `x`: shape {tuple(x.shape)}, expected (B, 1, {h}, {w})")
        return x

    def A(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """A x: (B, 1, H, W) → (B, M)."""
        return self.operator(self._check_x(x)[:, 0])

    def A_adjoint(self, y: torch.Tensor, **kwargs) -> torch.Tensor:
        """Aᵀ y: (B, M) → (B, 1, H, W)."""
        m = self.acquisition.measurements
        if not isinstance(y, torch.Tensor) or y.ndim != 2 or y.shape[1] != m:
            shape = tuple(y.shape) if isinstance(y, torch.Tensor) else type(y).__name__
            raise InputError(f"argument `y`: shape {shape}, expected (B, {m})")
        return self.operator.adjoint(y).unsqueeze(1)

    def simulate(self, x: torch.Tensor, seed: Optional[int] = None) -> torch.Tensor:
        """The bench's simulated measurement in volts, offset included (noise on), computed by
        the library on the host and returned on ``x``'s device and in its dtype."""
        self._check_x(x)
        if seed is None:
            seed, self._seed = self._seed, self._seed + 1
        y = self.acquisition.forward(_to_numpy(x, "x")[:, 0], noise=True, seed=int(seed),
                                     threads=self.threads)
        y = torch.from_numpy(np.asarray(y).reshape(x.shape[0], -1))
        return y.to(device=x.device, dtype=x.dtype)

    def remove_offset(self, y_v: torch.Tensor) -> torch.Tensor:
        """Recorded volts → the linear model's measurement, y_v − y₀."""
        return y_v - self.offset.to(device=y_v.device, dtype=y_v.dtype)

    def forward(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """Measurements with the offset removed (module documentation)."""
        if self.bench_noise:
            return self.remove_offset(self.simulate(x))
        return super().forward(x, **kwargs)
