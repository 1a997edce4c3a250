"""Type stubs of the extension module (the public API is the `spibench` package)."""

import enum
from typing import List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

class InputError(ValueError):
    """Input a user can fix; the message names the file, line and field or the argument."""

#: Every scheme's key.
SCHEMES: Tuple[str, ...]

def version() -> str:
    """The library's version."""
def dataset_noise_seed(seed: int, s: int) -> int:
    """Record seed of sample s of a dataset of spec seed `seed`."""

def make_dataset(spec: str, out: str, threads: Optional[int] = None) -> int:
    """`spibench dataset SPEC --out OUT`; returns the shards written."""

def dataset_contract() -> dict:
    """The dataset folder's tables: format, manifest, copies (provenance field → file),
    patterns, sample_arrays, cell_arrays (the kinds' prefixes), sequences, schemes."""

def dataset_array_name(kind: str, scheme: str, ratio: float) -> str:
    """The array name of `kind` (`meas`, `recon`, `score`) for a scheme and ratio."""
def dataset_array_names(schemes: Sequence[str], ratios: Sequence[float]) -> List[str]:
    """Every per-sample array name of a dataset of these schemes and ratios."""
def dataset_shard_dir(index: int) -> str:
    """The folder name of shard `index`."""
def read_dataset_manifest(path: str) -> str:
    """The folder's manifest as JSON text, read and checked by the library."""

class Arm(enum.Enum):
    """A detection arm (its photodiode), index 0 = +, 1 = −."""

    Plus = 0
    Minus = 1

class MirrorState(enum.Enum):
    """A powered mirror's state, index 0 = +, 1 = −."""

    Plus = 0
    Minus = 1

class Bench:
    """A bench file with its origin (the binding of `spibench.Bench`)."""

    @staticmethod
    def load(path: str) -> Bench:
        """Reads and checks a bench file (RON)."""
    @staticmethod
    def paper() -> Bench:
        """The paper's bench, built into the library."""
    @staticmethod
    def parse(text: str, path: str) -> Bench:
        """A bench from RON text; `path` names it in errors and resolves relative files."""
    def set(self, settings: List[Tuple[str, float]]) -> Bench:
        """A new bench with the (path, value) variables set, in order."""
    def get(self, path: str) -> float:
        """The value of a bench variable."""
    def variables(self) -> List[str]:
        """Every variable path of the bench, in file order."""
    def edits(self) -> List[Tuple[str, float]]:
        """The variables set since the file was read, in order."""
    def path(self) -> str:
        """The file the bench was read from (or the name it was given)."""
    def to_ron(self) -> str:
        """The bench as canonical RON text."""
    def check(self) -> Tuple[int, int]:
        """DMD units (down, across)."""
    def trace(self, rays: int, seed: int, threads: Optional[int] = None) -> Trace:
        """Traces `rays` lamp rays with `seed`."""
    def kernel(
        self,
        grid: Tuple[int, int],
        field_mm: Tuple[float, float],
        rays: int,
        seed: int,
        chart: Optional[str] = None,
        threads: Optional[int] = None,
    ) -> Kernel:
        """grid (H, W) pixels, field_mm (height_mm, width_mm)."""

class Trace:
    """A traced bench: metrics with standard errors, per-unit maps and the ledger."""

    rays: int
    seed: int
    units: Tuple[int, int]
    """(down, across)."""
    def values(self, reference: Optional[Trace] = None) -> List[Tuple[str, float]]:
        """(name, value) of what `spibench sweep` records: each metric, its standard error, and its
        paired difference from `reference` (this trace itself when None) with its standard error."""
    def x_w(self) -> F64:
        """x_j (W) per unit, units row-major (down, across)."""
    def g_a(self, arm: Arm) -> F64:
        """g_j (A) of one arm per unit."""
    def k_a_per_w(self, arm: Arm) -> F64:
        """k_j (A/W) of one arm per unit."""
    def k_stderr_a_per_w(self, arm: Arm) -> F64:
        """The standard error of k_j (A/W) of one arm per unit."""
    def t_a(self) -> F64:
        """T (A), the four blocks d·2 + s."""
    def ledger(self) -> dict:
        """The flux ledger: per mirror-state world, the power (W) absorbed per element, escaped,
        stopped at the path cap and detected."""

class Csr:
    """A sparse matrix in compressed rows."""

    data: F64
    indices: npt.NDArray[np.uint32]
    indptr: npt.NDArray[np.uint64]
    shape: Tuple[int, int]

class Estimate:
    """A Monte Carlo estimate and its standard error."""

    value: float
    stderr: float

class Product:
    """The kernel product of N objects."""

    x_w: F64
    """(N, units) (W)."""
    t_a: F64
    """(N, 4·units) (A), the four T blocks d·2 + s."""

class Kernel:
    """An object kernel: the traced transport from object pixels to DMD units and diodes."""

    grid: Tuple[int, int]
    field_mm: Tuple[float, float]
    units: Tuple[int, int]
    """(down, across)."""
    rays: int
    seed: int
    batches: int
    multi_crossing_current_fraction: float
    chart_current_a: float
    multi_crossing_current_a: float
    def t(self, arm: Arm, state: MirrorState) -> Csr:
        """T[arm][state] (units × pixels, A per unit transmittance)."""
    def t0(self, arm: Arm, state: MirrorState) -> F64:
        """The object-independent part of T[arm][state] per unit (A)."""
    def g(self, arm: Arm) -> Csr:
        """g[arm] (units × pixels, A per unit transmittance)."""
    def g_stderr(self, arm: Arm) -> Csr:
        """The standard error of g[arm], same sparsity."""
    def g0(self, arm: Arm) -> F64:
        """The object-independent part of g[arm] per unit (A)."""
    def x(self) -> Csr:
        """Power on each unit per unit transmittance (W), units × pixels."""
    def x0(self) -> F64:
        """The object-independent light per unit (W)."""
    def c(self, arm: Arm) -> F64:
        """The traced pattern-independent current of diode `arm` per pixel (A)."""
    def c0(self, arm: Arm) -> float:
        """The object-independent part of c[arm] (A)."""
    def transport_metrics(self, object: F64) -> List[Tuple[str, Estimate]]:
        """(name, estimate) of the transport metrics of one object."""
    def product(
        self, objects: F64, threads: Optional[int] = None, linear: bool = False
    ) -> Product:
        """The kernel product of each object row (with `linear`, its linear part)."""

class Coefficients:
    """y_i = ka·a_i + kb·b_i + ks₊·S₊ + ks₋·S₋ + kc₊·c₊ + kc₋·c₋ + const."""

    ka: float
    kb: float
    ks: Tuple[float, float]
    kc: Tuple[float, float]

class Solution:
    """A TVAL3 reconstruction and how the solver stopped."""

    image: F64
    """(down, across)."""
    iterations: int
    stop: str
    converged: bool
    relative_residual: float
    seconds: float

class Acquisition:
    """One scheme's traced acquisition: patterns, forward model, linear part and adjoint."""

    scheme: str
    measurements: int
    pixels: int
    units: Tuple[int, int]
    grid: Tuple[int, int]
    noise_default: bool
    recorded: List[str]
    offset: F64
    coefficients: Coefficients
    def __init__(
        self,
        kernel: Kernel,
        scheme: str,
        ratio: float,
        record: str = "frames",
        recorded: Optional[Sequence[str]] = None,
    ) -> None: ...
    def patterns(self) -> npt.NDArray[np.uint8]:
        """The M base patterns as 0/1, (M, down, across)."""
    def forward(
        self,
        objects: F64,
        noise: bool,
        seeds: npt.NDArray[np.uint64],
        threads: Optional[int] = None,
        linear: bool = False,
    ) -> F64:
        """Simulated measurements (V) (N, M) (with `linear`, through the kernel's linear part)."""
    def apply(self, objects: F64, threads: Optional[int] = None) -> F64:
        """A x, the linear part, (N, M) for objects (N, pixels)."""
    def adjoint(self, y: F64, threads: Optional[int] = None) -> F64:
        """Aᵀ y, (N, pixels) for y (N, M)."""
    def reconstruct(self, y: F64, threads: Optional[int] = None) -> Solution:
        """The library's TVAL3 reconstruction of one measurement."""
    def time_rust(self, objects: F64, adjoint: bool, repeats: int, threads: Optional[int] = None) -> float:
        """Seconds of the best of `repeats` library calls on the batch, without Python."""

class Dataset:
    """A dataset folder's spec with its kernel, for its acquisitions."""

    seed: int
    def __init__(self, path: str, threads: Optional[int] = None) -> None: ...
    def acquisition(self, scheme: str, ratio: float) -> Acquisition:
        """The acquisition of `scheme` at `ratio` as the dataset recorded it."""
    benches: int
    """The benches the samples were measured through (1: the nominal bench)."""
    def deviation_names(self) -> List[str]:
        """The names of a drawn bench's deviations (tolerances, then compensators)."""
    def drawn_bench(self, t: int) -> Tuple[Kernel, List[float]]:
        """Drawn bench `t`: its kernel (traced again) and its deviations."""
    def acquisition_on(self, kernel: Kernel, scheme: str, ratio: float) -> Acquisition:
        """The acquisition of `scheme` at `ratio` through `kernel`, as the dataset records."""
    def kernel(self) -> Kernel:
        """The dataset's object kernel."""
