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

def version() -> str: ...
def dataset_noise_seed(seed: int, s: int) -> int:
    """Record seed of sample s of a dataset of spec seed `seed`."""

def make_dataset(spec: str, out: str, threads: Optional[int] = None) -> int:
    """`spibench dataset SPEC --out OUT`; returns the shards written."""

def dataset_contract() -> dict:
    """The dataset folder's tables: format, manifest, copies (provenance field → file),
    patterns, sample_arrays, cell_arrays (the kinds' prefixes), sequences, schemes."""

def dataset_array_name(kind: str, scheme: str, ratio: float) -> str: ...
def dataset_array_names(schemes: Sequence[str], ratios: Sequence[float]) -> List[str]: ...
def dataset_shard_dir(index: int) -> str: ...
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
    @staticmethod
    def load(path: str) -> Bench: ...
    @staticmethod
    def paper() -> Bench: ...
    @staticmethod
    def parse(text: str, path: str) -> Bench: ...
    def set(self, settings: List[Tuple[str, float]]) -> Bench: ...
    def get(self, path: str) -> float: ...
    def variables(self) -> List[str]: ...
    def edits(self) -> List[Tuple[str, float]]: ...
    def path(self) -> str: ...
    def to_ron(self) -> str: ...
    def check(self) -> Tuple[int, int]:
        """DMD units (down, across)."""
    def trace(self, rays: int, seed: int, threads: Optional[int] = None) -> Trace: ...
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
    rays: int
    seed: int
    units: Tuple[int, int]
    """(down, across)."""
    def values(self, reference: Optional[Trace] = None) -> List[Tuple[str, float]]: ...
    def x_w(self) -> F64:
        """x_j (W) per unit, units row-major (down, across)."""
    def g_a(self, arm: Arm) -> F64: ...
    def k_a_per_w(self, arm: Arm) -> F64: ...
    def k_stderr_a_per_w(self, arm: Arm) -> F64: ...
    def t_a(self) -> F64:
        """T (A), the four blocks d·2 + s."""
    def ledger(self) -> dict: ...

class Csr:
    """A sparse matrix in compressed rows."""

    data: F64
    indices: npt.NDArray[np.uint32]
    indptr: npt.NDArray[np.uint64]
    shape: Tuple[int, int]

class Estimate:
    value: float
    stderr: float

class Product:
    """The kernel product of N objects."""

    x_w: F64
    """(N, units) (W)."""
    t_a: F64
    """(N, 4·units) (A), the four T blocks d·2 + s."""

class Kernel:
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
    def t(self, arm: Arm, state: MirrorState) -> Csr: ...
    def t0(self, arm: Arm, state: MirrorState) -> F64: ...
    def g(self, arm: Arm) -> Csr: ...
    def g_stderr(self, arm: Arm) -> Csr: ...
    def g0(self, arm: Arm) -> F64: ...
    def x(self) -> Csr: ...
    def x0(self) -> F64: ...
    def c(self, arm: Arm) -> F64: ...
    def c0(self, arm: Arm) -> float: ...
    def transport_metrics(self, object: F64) -> List[Tuple[str, Estimate]]: ...
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
    image: F64
    """(down, across)."""
    iterations: int
    stop: str
    converged: bool
    relative_residual: float
    seconds: float

class Acquisition:
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
    def patterns(self) -> npt.NDArray[np.uint8]: ...
    def forward(
        self,
        objects: F64,
        noise: bool,
        seeds: npt.NDArray[np.uint64],
        threads: Optional[int] = None,
        linear: bool = False,
    ) -> F64:
        """Simulated measurements (V) (N, M) (with `linear`, through the kernel's linear part)."""
    def apply(self, objects: F64, threads: Optional[int] = None) -> F64: ...
    def adjoint(self, y: F64, threads: Optional[int] = None) -> F64: ...
    def reconstruct(self, y: F64, threads: Optional[int] = None) -> Solution: ...
    def time_rust(self, objects: F64, adjoint: bool, repeats: int, threads: Optional[int] = None) -> float:
        """Seconds of the best of `repeats` library calls on the batch, without Python."""

class Dataset:
    seed: int
    def __init__(self, path: str, threads: Optional[int] = None) -> None: ...
    def acquisition(self, scheme: str, ratio: float) -> Acquisition: ...
    def kernel(self) -> Kernel: ...
