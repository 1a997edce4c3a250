"""The bench's noise reduced to a deepinv noise model of A x, on any device (needs torch and
deepinv).

The library simulates each measurement through the bench's electronics: the shot noise of each
photocurrent and the amplifiers' current noise through the detector's single pole, the
oscilloscope's input noise and its quantisation over each frame's settled window, and the
lamp and ambient drift over the sequence (``Acquisition.forward(noise=True)``; docs/ explain
each part). Over a frame's window these add up to a Gaussian whose variance has three kinds of
terms: constant ones (amplifier and oscilloscope noise, quantisation), ones proportional to the
photocurrents (shot noise), and one proportional to the square of the signal (a multiplicative
drift). :class:`BenchGaussianNoise` keeps that form for each measurement i of one scheme and
ratio, in volts,

    σ_i² = floor² + gain·max(v_i, 0) + light_gain·t̄ + (drift·v_i)²,

with v_i the noise-free recorded volts of measurement i and t̄ the object's mean transmittance
(the differencing schemes cancel the light in v_i, not its shot noise, which follows the total
light); the four coefficients are fitted (non-negative least squares, relative weights) to the
per-measurement variances of the library's own simulation of calibration objects
(:meth:`BenchGaussianNoise.fit`). It draws N(0, σ_i²) with its own ``torch.Generator`` on the
measurements' device: what a training loop needs on a GPU, where the exact simulation runs on
the host. The exact simulation stays available (``noise="bench"`` of
:class:`spibench.deepinv.TracedSinglePixel`).

The calibrated double-arm scheme divides each measurement by the object's own swings, so its
noise scales with the inverse square of the object's light: it is no Gaussian of A x and is
refused.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np
import torch
from deepinv.physics import NoiseModel

from . import Acquisition, InputError

__all__ = ["BenchGaussianNoise", "calibration_objects"]

#: Schemes whose measurement divides by the object's own light (no Gaussian of A x).
_SELF_NORMALISED = ("double_arm_calibrated",)


def calibration_objects(grid, seed: int = 0) -> np.ndarray:
    """The default calibration objects on ``grid``: uniform transmittances 0.1, 0.4, 0.7 and 1
    and four random textures (pixels uniform in [0, 1], and the same smoothed over 4 × 4
    blocks, at two mean levels), (8, H, W)."""
    h, w = grid
    rng = np.random.default_rng(seed)
    flat = [np.full((h, w), v) for v in (0.1, 0.4, 0.7, 1.0)]
    tex = [rng.random((h, w)), 0.4 * rng.random((h, w))]
    coarse = rng.random(((h + 3) // 4, (w + 3) // 4))
    block = np.kron(coarse, np.ones((4, 4)))[:h, :w]
    tex += [block, 0.5 + 0.5 * block]
    return np.stack(flat + tex)


def measured_moments(acquisition: Acquisition, objects: np.ndarray, records: int, seed: int,
                     threads: Optional[int] = None):
    """The library's simulation of each object ``records`` times (record seeds from
    ``seed``): (noise-free volts v, sample mean, sample variance), each (N, M)."""
    n = objects.shape[0]
    v = np.asarray(acquisition.forward(objects, noise=False, threads=threads)).reshape(n, -1)
    means, variances = [], []
    for j in range(n):
        seeds = [seed + j * records + r for r in range(records)]
        y = np.asarray(acquisition.forward(np.repeat(objects[j][None], records, 0), noise=True,
                                           seed=seeds, threads=threads))
        means.append(y.mean(0))
        variances.append(y.var(0, ddof=1))
    return v, np.stack(means), np.stack(variances)


def _design(v: np.ndarray, light: np.ndarray) -> np.ndarray:
    """The columns of σ² = floor² + gain·v⁺ + light_gain·t̄ + drift²·v² for volts v (N, M) and
    mean transmittances t̄ (N,)."""
    t = np.broadcast_to(light[:, None], v.shape)
    return np.stack([np.ones_like(v), np.maximum(v, 0), t, v * v], axis=-1).reshape(-1, 4)


class BenchGaussianNoise(NoiseModel):
    """The bench's noise of one scheme and ratio as a signal-dependent Gaussian (module
    documentation), on the physics' measurements y = (v − y₀)/scale: σ_i(y) in volts divided by
    ``scale``.

    :param coefficients: (floor², gain, light_gain, drift²) in V², V, V², 1.
    :param offset: y₀ (M,) (V) of the physics.
    :param float scale: the physics' scale (V per unit of its measurements).
    :param float light: t̄ assumed when a call gives none (default 0.5).
    :param rng: the ``torch.Generator`` of the draws (default: a new one on ``device``).
    """

    def __init__(self, coefficients: Sequence[float], offset, scale: float = 1.0,
                 light: float = 0.5, rng: Optional[torch.Generator] = None, device="cpu",
                 dtype=torch.float32):
        c = np.asarray(coefficients, dtype=np.float64)
        if c.shape != (4,) or not np.all(np.isfinite(c)) or np.any(c < 0):
            raise InputError(f"argument `coefficients`: four non-negative numbers, got {coefficients}")
        if rng is None:
            rng = torch.Generator(device=device)
            rng.manual_seed(0)
        super().__init__(rng=rng)
        f = dict(dtype=dtype, device=device)
        self.register_buffer("coefficients", torch.tensor(c, **f))
        self.register_buffer("offset", torch.as_tensor(np.asarray(offset, dtype=np.float64)).to(**f))
        self.register_buffer("scale", torch.tensor(float(scale), **f))
        self.register_buffer("light", torch.tensor(float(light), **f))

    @classmethod
    def fit(cls, acquisition: Acquisition, scale: float = 1.0,
            objects: Optional[np.ndarray] = None, records: int = 32, seed: int = 1 << 32,
            threads: Optional[int] = None, **kwargs) -> "BenchGaussianNoise":
        """The model fitted to the library's simulation of ``acquisition``: each calibration
        object (default :func:`calibration_objects`) recorded ``records`` times, the four
        coefficients by non-negative least squares on the per-measurement sample variances,
        each row weighted by the inverse of the model's variance (iterated). ``scale`` is the physics' (``physics.scale``);
        ``kwargs`` go to the constructor (``rng``, ``device``, ``dtype``)."""
        if not isinstance(acquisition, Acquisition):
            raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
        if acquisition.scheme in _SELF_NORMALISED:
            raise InputError(f"argument `acquisition`: the {acquisition.scheme} scheme divides by "
                             "the object's own light; its noise is no Gaussian of A x")
        if int(records) < 4:
            raise InputError(f"argument `records`: at least 4, got {records}")
        obj = calibration_objects(acquisition.grid) if objects is None else np.asarray(objects, float)
        v, _, var = measured_moments(acquisition, obj, int(records), int(seed), threads)
        from scipy.optimize import nnls

        a = _design(v, obj.reshape(obj.shape[0], -1).mean(1))
        b = var.reshape(-1)
        tiny = np.finfo(float).tiny
        # Relative weights 1/σ², σ² the model's own (iterated from the sample variances'):
        # weighting by a sample variance favours the low ones and biases the fit low by about
        # 2/(records − 1).
        pred = np.full_like(b, max(float(b.mean()), tiny))
        for _ in range(4):
            w = 1.0 / np.maximum(pred, tiny)
            # Columns scaled to unit size so that the solver's tolerance treats them alike.
            col = np.maximum(np.abs(a * w[:, None]).max(0), tiny)
            c, _ = nnls(a * w[:, None] / col, b * w)
            c = c / col
            pred = a @ c
        model = cls(c, acquisition.offset, scale, **kwargs)
        model.calibration = {"objects": obj.shape[0], "records": int(records)}
        return model

    def variance_v(self, v: torch.Tensor, light: Optional[torch.Tensor] = None) -> torch.Tensor:
        """σ² (V²) of noise-free volts v (B, M), for mean transmittances ``light`` (B,)."""
        f2, g, gl, d2 = self.coefficients.to(v.dtype)
        t = self.light.to(v.dtype) if light is None else light.to(v.dtype).reshape(-1, 1)
        return f2 + g * v.clamp(min=0) + gl * t + d2 * v * v

    def sigma(self, y: torch.Tensor, light: Optional[torch.Tensor] = None) -> torch.Tensor:
        """σ of each measurement y (B, M) in the physics' units."""
        s = self.scale.to(y.dtype)
        v = y * s + self.offset.to(y.dtype)
        return self.variance_v(v, light).sqrt() / s

    def forward(self, y: torch.Tensor, seed: Optional[int] = None, light=None,
                **kwargs) -> torch.Tensor:
        """y + N(0, σ(y)²), drawn with the model's generator on y's device."""
        return y + self.sigma(y, light) * self.randn_like(y, seed=seed)

    def extra_repr(self) -> str:
        """The coefficients in volts."""
        f2, g, gl, d2 = (float(c) for c in self.coefficients)
        return (f"σ² = {f2:.3e} V² + {g:.3e} V·max(v, 0) + {gl:.3e} V²·t̄ + ({d2 ** 0.5:.3e}·v)², "
                f"scale={float(self.scale):.4e} V")
