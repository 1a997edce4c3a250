"""deepinv adapter: a traced spibench acquisition as a ``deepinv.physics.LinearPhysics``.

Optional: importing this module needs ``torch`` and ``deepinv``; the rest of spibench needs
numpy and scipy only.

deepinv's physics are linear, y = N(A x). spibench's measurement is affine,
y_V = A_V x + y₀ (V) plus the bench's noise, so the adapter works with the offset removed and,
by default, normalised as deepinv's own operators are (‖A‖ = 1), so that deepinv's solvers and
their usual parameters apply (a TV prior with λ = 1e-3, a step size of 1):

- ``physics.A(x) = A_V x / s`` with s = ‖A_V‖ (``physics.scale``, V per unit transmittance;
  ``normalise=False`` keeps volts, s = 1), ``A_adjoint`` its exact adjoint, on tensors of shape
  (B, 1, H, W) and (B, M), computed by torch on the module's device and in its dtype
  (:class:`spibench.nn.TracedLinear`, float32 by default; ``.double()``, ``.to(device)``);
  autograd goes through the adjoint, so unrolled networks train through them;
- ``physics(x)`` (``forward``) gives y = (y_V − y₀)/s: with ``noise="bench"`` (the default)
  from the bench's own simulated measurement (detector, oscilloscope, drift and noise:
  ``Acquisition.forward(noise=True)``, computed by the library on the host and returned on the
  input's device; the printed physics shows it as ``noise_model: BenchSimulation(…)``); with a
  deepinv noise model, that model applied to A x (:class:`spibench.noise.BenchGaussianNoise`
  is the bench's noise reduced to a signal-dependent Gaussian, on the device);
- ``physics.remove_offset(y_v)`` turns recorded volts (a dataset's ``meas_…`` arrays) into
  what ``A`` models, ``physics.to_volts(y)`` back; ``physics.offset`` is y₀ (V).

:class:`TracedBenches` is the same physics over several benches as built (drawn from a
tolerance file: one traced kernel each), the bench of each sample a parameter, and
:class:`BenchGenerator` the deepinv ``PhysicsGenerator`` that draws it per sample.
:class:`LinearisedBench` is the first-order expansion of the acquisition in chosen bench
variables, from paired central differences of traced kernels (common random numbers), and
:class:`DeviationGenerator` draws its deviations per sample.
"""

from __future__ import annotations

from typing import Optional, Sequence, Union

import numpy as np
import torch
from deepinv.physics import LinearPhysics, NoiseModel
from deepinv.physics.generator import PhysicsGenerator

from . import Acquisition, InputError, Kernel
from .nn import TracedLinear, _pack_patterns, _patterns_adjoint, _patterns_apply
from .noise import BenchGaussianNoise

__all__ = ["TracedSinglePixel", "TracedBenches", "BenchGenerator", "BenchSimulation",
           "LinearisedBench", "DeviationGenerator"]


def _to_numpy(t: torch.Tensor, name: str) -> np.ndarray:
    """``t`` as a float64 numpy array on the host (the bench simulation's input)."""
    if not isinstance(t, torch.Tensor):
        raise InputError(f"argument `{name}`: a torch.Tensor is needed, got {type(t).__name__}")
    if t.is_complex():
        raise InputError(f"argument `{name}`: complex tensors are not supported")
    return t.detach().to("cpu", torch.float64).contiguous().numpy()


class BenchSimulation(NoiseModel):
    """The bench's own noise: the library's full simulation of the detector, oscilloscope,
    drift and noise (``Acquisition.forward(noise=True)``) on the host. It measures the object,
    not A x, so the physics applies it (``physics(x)``); called on measurements alone it
    refuses. Record seeds: ``seed``, then the next one at each call."""

    def __init__(self, scheme: str, seed: int = 0, threads: Optional[int] = None):
        super().__init__()
        self.scheme = str(scheme)
        self.seed = int(seed)
        self.threads = threads

    def next_seed(self) -> int:
        """The record seed of the next call (and advances it)."""
        s, self.seed = self.seed, self.seed + 1
        return s

    def forward(self, y: torch.Tensor, *args, **kwargs) -> torch.Tensor:
        """Refused: the simulation needs the object (use ``physics(x)``)."""
        raise InputError("BenchSimulation measures the object through the bench: call physics(x), "
                         "not physics.noise(y); for a noise model of A x use "
                         "spibench.noise.BenchGaussianNoise")

    def extra_repr(self) -> str:
        """The scheme and the next record seed."""
        return (f"scheme={self.scheme}, next_seed={self.seed}: the library's simulation of the "
                f"bench's detector, oscilloscope, drift and noise (CPU)")


def _noise_model(noise, acquisition: Acquisition, seed: int, threads: Optional[int],
                 scale: float, dtype, device):
    """The physics' noise model of the ``noise`` argument."""
    if isinstance(noise, torch.nn.Module):
        return noise
    if noise == "bench":
        return BenchSimulation(acquisition.scheme, seed, threads)
    if noise == "gaussian":
        rng = torch.Generator(device=device or "cpu")
        rng.manual_seed(int(seed))
        return BenchGaussianNoise.fit(acquisition, scale=scale, threads=threads, rng=rng,
                                      dtype=dtype, device=device or "cpu")
    if noise is None:
        return None
    raise InputError(f"argument `noise`: \"bench\", \"gaussian\", None or a deepinv noise "
                     f"model, got {noise!r}")


class TracedSinglePixel(LinearPhysics):
    """The traced single-pixel acquisition ``acquisition`` as deepinv physics (module
    documentation). Images are (B, 1, H, W) on the kernel grid (transmittance); measurements
    (B, M), offset removed, divided by ``scale``.

    :param Acquisition acquisition: the spibench acquisition (scheme, ratio, kernel).
    :param noise: ``"bench"`` (the bench's simulated electronics and noise, on the host),
        ``"gaussian"`` (the same reduced to :class:`spibench.noise.BenchGaussianNoise`, fitted
        here to the library's simulation, drawn on the device), ``None`` (none), or a deepinv
        noise model applied to ``A x``.
    :param int seed: record seed of the bench noise (each call draws the next seeds), or the
        seed of the Gaussian model's generator.
    :param int threads: library threads of the bench simulation (default: all cores).
    :param Kernel kernel: the acquisition's object kernel: A is then held as its sparse
        matrices (:class:`spibench.nn.TracedLinear`); without it, as a dense matrix read from
        the acquisition (small sizes only).
    :param dtype: ``torch.float32`` (default) or ``torch.float64``.
    :param device: where the operator's buffers go (default: CPU).
    :param bool normalise: divide A by its spectral norm (default), so ‖A‖ = 1 as deepinv's
        operators; ``False`` keeps volts.
    :param float scale: the divisor itself, instead of ‖A‖ (several physics sharing one).
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
        normalise: bool = True,
        scale: Optional[float] = None,
        **kwargs,
    ):
        if not isinstance(acquisition, Acquisition):
            raise InputError("argument `acquisition`: a spibench.Acquisition is needed")
        h, w = acquisition.grid
        s = _scale(acquisition, normalise, scale)
        model = _noise_model(noise, acquisition, seed, threads, s, dtype, device)
        super().__init__(img_size=(1, h, w), noise_model=model, **kwargs)
        self.acquisition = acquisition
        self.operator = TracedLinear(acquisition, kernel, dtype=dtype, device=device)
        self.register_buffer("scale", torch.tensor(s, dtype=dtype, device=device))
        self.threads = threads

    @property
    def offset(self) -> torch.Tensor:
        """y₀ (M,) (V), the measurement of the black object, on the operator's device and
        dtype."""
        return self.operator.offset

    @property
    def bench_noise(self) -> bool:
        """Whether ``physics(x)`` is the bench's own simulation."""
        return isinstance(self.noise_model, BenchSimulation)

    def _check_x(self, x: torch.Tensor) -> torch.Tensor:
        """``x`` itself, refused unless a (B, 1, H, W) tensor on the kernel grid."""
        h, w = self.acquisition.grid
        if not isinstance(x, torch.Tensor):
            raise InputError(f"argument `x`: a torch.Tensor is needed, got {type(x).__name__}")
        if x.ndim != 4 or tuple(x.shape[1:]) != (1, h, w):
            raise InputError(f"argument `x`: shape {tuple(x.shape)}, expected (B, 1, {h}, {w})")
        return x

    def _check_y(self, y: torch.Tensor) -> torch.Tensor:
        m = self.acquisition.measurements
        if not isinstance(y, torch.Tensor) or y.ndim != 2 or y.shape[1] != m:
            shape = tuple(y.shape) if isinstance(y, torch.Tensor) else type(y).__name__
            raise InputError(f"argument `y`: shape {shape}, expected (B, {m})")
        return y

    def A(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """A x: (B, 1, H, W) → (B, M)."""
        return self.operator(self._check_x(x)[:, 0]) / self.scale

    def A_adjoint(self, y: torch.Tensor, **kwargs) -> torch.Tensor:
        """Aᵀ y: (B, M) → (B, 1, H, W)."""
        return (self.operator.adjoint(self._check_y(y)) / self.scale).unsqueeze(1)

    def simulate(self, x: torch.Tensor, seed: Optional[int] = None) -> torch.Tensor:
        """The bench's simulated measurement in volts, offset included (noise on), computed by
        the library on the host and returned on ``x``'s device and in its dtype."""
        self._check_x(x)
        if seed is None:
            sim = self.noise_model if self.bench_noise else None
            seed = sim.next_seed() if sim is not None else 0
        threads = self.noise_model.threads if self.bench_noise else self.threads
        y = self.acquisition.forward(_to_numpy(x, "x")[:, 0], noise=True, seed=int(seed),
                                     threads=threads)
        y = torch.from_numpy(np.asarray(y).reshape(x.shape[0], -1))
        return y.to(device=x.device, dtype=x.dtype)

    def remove_offset(self, y_v: torch.Tensor) -> torch.Tensor:
        """Recorded volts → the physics' measurement, (y_v − y₀) / scale."""
        off = self.offset.to(device=y_v.device, dtype=y_v.dtype)
        return (y_v - off) / self.scale.to(device=y_v.device, dtype=y_v.dtype)

    def to_volts(self, y: torch.Tensor) -> torch.Tensor:
        """The physics' measurement → volts, y·scale + y₀."""
        return y * self.scale.to(y.device, y.dtype) + self.offset.to(y.device, y.dtype)

    def forward(self, x: torch.Tensor, **kwargs) -> torch.Tensor:
        """Measurements, offset removed and divided by ``scale`` (module documentation)."""
        if self.bench_noise:
            return self.remove_offset(self.simulate(x))
        if isinstance(self.noise_model, BenchGaussianNoise):
            # The shot noise of the differencing schemes follows the object's total light.
            return self.noise_model(self.A(x), light=x.mean(dim=(1, 2, 3)))
        return super().forward(x, **kwargs)


def _scale(acquisition: Acquisition, normalise: bool, scale: Optional[float]) -> float:
    """The divisor of the normalised physics."""
    if scale is not None:
        s = float(scale)
        if not (np.isfinite(s) and s > 0):
            raise InputError(f"argument `scale`: a positive number, got {scale!r}")
        return s
    return acquisition.operator_norm() if normalise else 1.0


class TracedBenches(LinearPhysics):
    """The traced acquisition over K benches as built (each its own traced kernel, the same
    patterns and scheme): sample b of a batch is measured through bench ``bench[b]``, a
    parameter that ``physics.update(bench=…)`` sets (deepinv's trainers do so with the
    parameters of :class:`BenchGenerator`); one index for the whole batch when it holds one.
    Measurements are offset-removed (each bench its own y₀) and divided by one ``scale`` for
    all benches (default: ‖A‖ of bench 0), so they share units.

    :param acquisitions: one :class:`spibench.Acquisition` per bench.
    :param kernels: their kernels (sparse operators), or ``None`` (dense, small sizes).
    :param noise: ``"bench"``, ``None`` or a deepinv noise model, as for
        :class:`TracedSinglePixel`.
    """

    def __init__(
        self,
        acquisitions: Sequence[Acquisition],
        kernels: Optional[Sequence[Kernel]] = None,
        noise: Union[str, None, torch.nn.Module] = "bench",
        seed: int = 0,
        threads: Optional[int] = None,
        dtype: torch.dtype = torch.float32,
        device=None,
        normalise: bool = True,
        scale: Optional[float] = None,
        **kwargs,
    ):
        acqs = list(acquisitions)
        if not acqs or not all(isinstance(a, Acquisition) for a in acqs):
            raise InputError("argument `acquisitions`: a non-empty sequence of spibench.Acquisition")
        ks = [None] * len(acqs) if kernels is None else list(kernels)
        if len(ks) != len(acqs):
            raise InputError(f"argument `kernels`: {len(ks)} kernels for {len(acqs)} acquisitions")
        a0 = acqs[0]
        for a in acqs[1:]:
            if (a.grid, a.measurements, a.scheme) != (a0.grid, a0.measurements, a0.scheme):
                raise InputError("argument `acquisitions`: every bench needs the same grid, "
                                 "scheme and number of measurements")
        h, w = a0.grid
        s = _scale(a0, normalise, scale)
        if noise == "gaussian":
            raise InputError("argument `noise`: \"bench\", None or a deepinv noise model (a "
                             "BenchGaussianNoise fitted to one of the benches)")
        model = _noise_model(noise, a0, seed, threads, s, dtype, device)
        super().__init__(img_size=(1, h, w), noise_model=model, **kwargs)
        self.acquisitions = acqs
        self.operators = torch.nn.ModuleList(
            TracedLinear(a, k, dtype=dtype, device=device) for a, k in zip(acqs, ks))
        self.register_buffer("scale", torch.tensor(s, dtype=dtype, device=device))
        self.register_buffer("bench", torch.zeros(1, dtype=torch.int64, device=device))

    @property
    def benches(self) -> int:
        """K, the number of benches."""
        return len(self.operators)

    @property
    def bench_noise(self) -> bool:
        """Whether ``physics(x)`` is the bench's own simulation."""
        return isinstance(self.noise_model, BenchSimulation)

    def update_parameters(self, bench=None, **kwargs):
        """Sets the bench index of each sample (an int, or a (B,) integer tensor)."""
        if bench is not None:
            b = torch.as_tensor(bench, dtype=torch.int64).reshape(-1)
            if b.numel() == 0 or int(b.min()) < 0 or int(b.max()) >= self.benches:
                raise InputError(f"argument `bench`: indices in 0…{self.benches - 1}, got {bench}")
            self.bench = b.to(self.scale.device)
        super().update_parameters(**kwargs)

    def _groups(self, n: int):
        """(bench k, sample indices) of a batch of n."""
        b = self.bench
        if b.numel() == 1:
            return [(int(b), None)]
        if b.numel() != n:
            raise InputError(f"parameter `bench`: {b.numel()} indices for a batch of {n}")
        return [(int(k), torch.nonzero(b == k).reshape(-1)) for k in torch.unique(b).tolist()]

    def _per_bench(self, v: torch.Tensor, f, out_shape):
        groups = self._groups(v.shape[0])
        if groups[0][1] is None:
            return f(groups[0][0], v)
        out = v.new_zeros((v.shape[0],) + out_shape)
        for k, idx in groups:
            out = out.index_copy(0, idx, f(k, v.index_select(0, idx)))
        return out

    def A(self, x: torch.Tensor, bench=None, **kwargs) -> torch.Tensor:
        """A x through each sample's bench: (B, 1, H, W) → (B, M)."""
        self.update_parameters(bench=bench)
        m = self.acquisitions[0].measurements
        return self._per_bench(x[:, 0], lambda k, v: self.operators[k](v), (m,)) / self.scale

    def A_adjoint(self, y: torch.Tensor, bench=None, **kwargs) -> torch.Tensor:
        """Aᵀ y through each sample's bench: (B, M) → (B, 1, H, W)."""
        self.update_parameters(bench=bench)
        grid = self.acquisitions[0].grid
        x = self._per_bench(y, lambda k, v: self.operators[k].adjoint(v), grid)
        return (x / self.scale).unsqueeze(1)

    def offsets(self, n: int) -> torch.Tensor:
        """y₀ (V) of each sample's bench, (n, M)."""
        m = self.acquisitions[0].measurements
        off = torch.stack([op.offset for op in self.operators])
        b = self.bench if self.bench.numel() > 1 else self.bench.expand(n)
        return off.index_select(0, b).reshape(n, m)

    def forward(self, x: torch.Tensor, bench=None, **kwargs) -> torch.Tensor:
        """Measurements through each sample's bench, offset removed and divided by ``scale``."""
        self.update_parameters(bench=bench)
        if not self.bench_noise:
            return super().forward(x, **kwargs)
        sim = self.noise_model
        seed = sim.next_seed()
        xs = _to_numpy(x, "x")[:, 0]
        y = torch.empty(x.shape[0], self.acquisitions[0].measurements, dtype=torch.float64)
        for k, idx in self._groups(x.shape[0]):
            rows = np.arange(x.shape[0]) if idx is None else idx.cpu().numpy()
            # Sample b keeps the record seed it would have in one call over the batch.
            seeds = [_record_seed(seed, int(r)) for r in rows]
            y[rows] = torch.from_numpy(np.asarray(self.acquisitions[k].forward(
                xs[rows], noise=True, seed=seeds, threads=sim.threads)).reshape(len(rows), -1))
        return self.remove_offset(y.to(device=x.device, dtype=x.dtype))

    def remove_offset(self, y_v: torch.Tensor, bench=None) -> torch.Tensor:
        """Recorded volts of each sample's bench → the physics' measurement,
        (y_v − y₀[bench]) / scale."""
        self.update_parameters(bench=bench)
        off = self.offsets(y_v.shape[0]).to(device=y_v.device, dtype=y_v.dtype)
        return (y_v - off) / self.scale.to(device=y_v.device, dtype=y_v.dtype)


def _record_seed(seed: int, s: int) -> int:
    from . import dataset_noise_seed

    return dataset_noise_seed(seed, s)


class BenchGenerator(PhysicsGenerator):
    """deepinv ``PhysicsGenerator`` of :class:`TracedBenches`: each sample's bench drawn
    uniformly from the K benches, with this generator's own ``torch.Generator``:
    ``step(batch_size)`` returns ``{"bench": (B,) int64}``."""

    def __init__(self, benches: int, rng: Optional[torch.Generator] = None, device="cpu",
                 seed: Optional[int] = None):
        if int(benches) < 1:
            raise InputError(f"argument `benches`: at least 1, got {benches}")
        super().__init__(rng=rng, device=device)
        self.benches = int(benches)
        if seed is not None:
            self.rng.manual_seed(int(seed))
            self.initial_random_state = self.rng.get_state()

    def step(self, batch_size: int = 1, seed: Optional[int] = None, **kwargs) -> dict:
        """``{"bench": …}``: the bench index of each of ``batch_size`` samples."""
        self.rng_manual_seed(seed)
        b = torch.randint(0, self.benches, (batch_size,), generator=self.rng, device=self.device)
        return {"bench": b}


class LinearisedBench(LinearPhysics):
    """The traced acquisition of a bench whose chosen variables deviate by δ from the nominal,
    to first order: each variable's derivative from a paired central difference of two traced
    kernels, every kernel traced with the same rays and seed (common random numbers, so the
    Monte Carlo noise of the two cancels in their difference where their paths agree),

        A(δ) = A₀ + Σᵢ δᵢ (A(v₀ + hᵢeᵢ) − A(v₀ − hᵢeᵢ)) / (2hᵢ),   y₀(δ) likewise,

    each A the acquisition's linear part folded as :class:`spibench.nn.TracedLinear` holds it
    (A t = P (G t) + (r·t) 1), so the expansion is that of the kernel matrices G and r with the
    scheme's coefficients of each traced bench. Sample b of a batch is measured through
    A(δ_b), ``deviation`` a (B, V) parameter that ``physics.update(deviation=…)`` sets
    (:class:`DeviationGenerator` draws it per sample); one row for the whole batch when it holds
    one. The expansion is exact where the kernel is linear in a variable (a diode's
    responsivity scale) and otherwise good to the variable's curvature over hᵢ and δ: 1 + 2V
    kernels are traced instead of one per bench, and any δ within the steps costs nothing more.
    Measurements are offset-removed and divided by ``scale`` (default ‖A₀‖); G is held dense
    (V + 1 matrices of units × pixels) and the patterns bit-packed as in
    :class:`spibench.nn.TracedLinear` (the buffer ``patterns``, uint8 (M, ⌈units/8⌉), unpacked
    in blocks of rows on the device at each call), and the adjoint is autograd's of these
    products, exact.
    The noise model is deepinv's (``None`` by default; the bench simulation needs a traced
    bench, so ``"bench"`` is refused).

    :param Bench bench: the nominal bench.
    :param steps: ``{variable path: hᵢ}``, the half-step of each variable's central difference
        (units as in the path's name).
    :param grid: (H, W) object pixels; ``field_mm``, ``rays``, ``seed``: as
        :meth:`spibench.Bench.kernel` (one seed for all 1 + 2V kernels).
    :param str scheme: the acquisition scheme; ``ratio`` its sampling ratio.
    """

    def __init__(
        self,
        bench,
        steps,
        grid,
        field_mm,
        rays: int,
        seed: int = 1,
        scheme: str = "secondary_complementary_balancing",
        ratio: float = 0.25,
        threads: Optional[int] = None,
        dtype: torch.dtype = torch.float32,
        device=None,
        normalise: bool = True,
        scale: Optional[float] = None,
        noise_model=None,
        **kwargs,
    ):
        from . import Bench

        if not isinstance(bench, Bench):
            raise InputError("argument `bench`: a spibench.Bench is needed")
        names, hs = _steps(bench, steps)
        if isinstance(noise_model, str):
            raise InputError("argument `noise_model`: a deepinv noise model or None (the bench "
                             "simulation needs a traced bench: use TracedBenches)")

        def acq(settings):
            b = bench.set(settings) if settings else bench
            k = b.kernel(grid, field_mm, rays, seed=seed, threads=threads)
            return Acquisition(k, scheme, ratio), k

        a0, k0 = acq({})
        h, w = a0.grid
        s = _scale(a0, normalise, scale)
        super().__init__(img_size=(1, h, w), noise_model=noise_model, **kwargs)
        g0, r0 = _folded_dense(a0, k0)
        dg, dr, dy = [], [], []
        for name, step in zip(names, hs):
            v0 = bench.get(name)
            (ap, kp), (am, km) = acq({name: v0 + step}), acq({name: v0 - step})
            if not np.array_equal(ap.patterns, a0.patterns) or not np.array_equal(
                    am.patterns, a0.patterns):
                raise InputError(f"steps `{name}`: the bench's patterns change with it")
            (gp, rp), (gm, rm) = _folded_dense(ap, kp), _folded_dense(am, km)
            dg.append((gp - gm) / (2 * step))
            dr.append((rp - rm) / (2 * step))
            dy.append((np.asarray(ap.offset) - np.asarray(am.offset)) / (2 * step))
        m = a0.measurements
        units = g0.shape[0]
        t = dict(dtype=torch.float64)
        self.variables = names
        self.steps = hs
        self.acquisition = a0
        self.kernel = k0
        self.register_buffer("g0", torch.from_numpy(g0))
        self.register_buffer("dg", torch.from_numpy(np.stack(dg)) if dg
                             else torch.zeros(0, units, h * w, **t))
        self.register_buffer("r0", torch.from_numpy(r0))
        self.register_buffer("dr", torch.from_numpy(np.stack(dr)) if dr
                             else torch.zeros(0, h * w, **t))
        self.register_buffer("y0", torch.tensor(np.asarray(a0.offset), **t))
        self.register_buffer("dy0", torch.from_numpy(np.stack(dy)) if dy
                             else torch.zeros(0, m, **t))
        self.units = int(units)
        self.register_buffer("patterns", _pack_patterns(a0))
        self.register_buffer("scale", torch.tensor(s, **t))
        self.register_buffer("deviation", torch.zeros(1, len(names), **t))
        self.to(device=device, dtype=dtype)

    def update_parameters(self, deviation=None, **kwargs):
        """Sets δ of each sample: (V,) for the whole batch or (B, V), in the variables' units
        (order of :attr:`variables`)."""
        if deviation is not None:
            # Numbers given as such keep the physics' precision (a float32 tensor stays float32).
            d = (deviation if isinstance(deviation, torch.Tensor)
                 else torch.as_tensor(deviation, dtype=self.g0.dtype))
            if d.ndim == 1:
                d = d.reshape(1, -1)
            if d.ndim != 2 or d.shape[1] != len(self.variables):
                raise InputError(f"argument `deviation`: shape {tuple(d.shape)}, expected (B, "
                                 f"{len(self.variables)}) or ({len(self.variables)},)")
            self.deviation = d.to(device=self.g0.device, dtype=self.g0.dtype)
        super().update_parameters(**kwargs)

    def _delta(self, n: int) -> torch.Tensor:
        d = self.deviation
        if d.shape[0] == 1:
            return d.expand(n, -1)
        if d.shape[0] != n:
            raise InputError(f"parameter `deviation`: {d.shape[0]} rows for a batch of {n}")
        return d

    def A(self, x: torch.Tensor, deviation=None, **kwargs) -> torch.Tensor:
        """A(δ_b) x_b: (B, 1, H, W) → (B, M)."""
        self.update_parameters(deviation=deviation)
        xf = x.reshape(x.shape[0], -1)
        d = self._delta(xf.shape[0])
        u = xf @ self.g0.T + torch.einsum("bv,vup,bp->bu", d, self.dg, xf)
        r = self.r0 + d @ self.dr
        y = _patterns_apply(self.patterns, self.units, u) + (xf * r).sum(dim=1, keepdim=True)
        return y / self.scale

    def A_adjoint(self, y: torch.Tensor, deviation=None, **kwargs) -> torch.Tensor:
        """A(δ_b)ᵀ y_b: (B, M) → (B, 1, H, W)."""
        self.update_parameters(deviation=deviation)
        d = self._delta(y.shape[0])
        v = _patterns_adjoint(self.patterns, self.units, y)
        t = v @ self.g0 + torch.einsum("bv,vup,bu->bp", d, self.dg, v)
        t = t + y.sum(dim=1, keepdim=True) * (self.r0 + d @ self.dr)
        h, w = self.acquisition.grid
        return (t / self.scale).reshape(y.shape[0], 1, h, w)

    def offsets(self, n: int) -> torch.Tensor:
        """y₀(δ_b) (V) of each of n samples, (n, M)."""
        return self.y0 + self._delta(n) @ self.dy0

    def remove_offset(self, y_v: torch.Tensor, deviation=None) -> torch.Tensor:
        """Volts of each sample's bench → the physics' measurement, (y_v − y₀(δ_b)) / scale."""
        self.update_parameters(deviation=deviation)
        off = self.offsets(y_v.shape[0]).to(device=y_v.device, dtype=y_v.dtype)
        return (y_v - off) / self.scale.to(device=y_v.device, dtype=y_v.dtype)


def _steps(bench, steps):
    """The variable paths and half-steps of ``steps``, checked against the bench."""
    if not hasattr(steps, "items"):
        raise InputError("argument `steps`: a mapping of variable path to half-step is needed")
    known = set(bench.variables())
    names, hs = [], []
    for name, h in steps.items():
        if name not in known:
            raise InputError(f"argument `steps`: `{name}` is not a variable of the bench")
        try:
            hv = float(h)
        except (TypeError, ValueError):
            raise InputError(f"steps `{name}`: {h!r} is not a number") from None
        if not (np.isfinite(hv) and hv > 0):
            raise InputError(f"steps `{name}`: the half-step must be positive, got {h!r}")
        names.append(str(name))
        hs.append(hv)
    return names, hs


def _folded_dense(acquisition: Acquisition, kernel: Kernel):
    """G (units × pixels, dense) and r (pixels,) of ``acquisition`` on ``kernel``, float64."""
    from .nn import _folded

    g, r = _folded(acquisition, kernel)
    return g.toarray(), np.ascontiguousarray(r, dtype=np.float64)


class DeviationGenerator(PhysicsGenerator):
    """deepinv ``PhysicsGenerator`` of :class:`LinearisedBench`: each sample's deviations δ
    drawn independently per variable, uniform on ±``ranges[i]`` or, with ``sigmas``, normal
    with those standard deviations (units of the variables' paths), with this generator's own
    ``torch.Generator``: ``step(batch_size)`` returns ``{"deviation": (B, V)}``."""

    def __init__(self, ranges=None, sigmas=None, rng: Optional[torch.Generator] = None,
                 device="cpu", seed: Optional[int] = None, dtype: torch.dtype = torch.float32):
        if (ranges is None) == (sigmas is None):
            raise InputError("DeviationGenerator: give `ranges` (uniform) or `sigmas` (normal)")
        v = np.asarray(ranges if sigmas is None else sigmas, dtype=np.float64).reshape(-1)
        if v.size == 0 or not np.all(np.isfinite(v)) or np.any(v < 0):
            which = "ranges" if sigmas is None else "sigmas"
            raise InputError(f"argument `{which}`: non-negative finite numbers, got {v.tolist()}")
        super().__init__(rng=rng, device=device)
        self.normal = sigmas is not None
        self.widths = torch.tensor(v, dtype=dtype, device=device)
        if seed is not None:
            self.rng.manual_seed(int(seed))
            self.initial_random_state = self.rng.get_state()

    def step(self, batch_size: int = 1, seed: Optional[int] = None, **kwargs) -> dict:
        """``{"deviation": …}``: δ of each of ``batch_size`` samples, (B, V)."""
        self.rng_manual_seed(seed)
        shape = (batch_size, self.widths.numel())
        w = self.widths
        if self.normal:
            d = torch.randn(shape, generator=self.rng, device=self.device, dtype=w.dtype)
        else:
            d = 2 * torch.rand(shape, generator=self.rng, device=self.device, dtype=w.dtype) - 1
        return {"deviation": d * w}
