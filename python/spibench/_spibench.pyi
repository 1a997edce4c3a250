"""Type stubs of the extension module (the public API is spibench/__init__.py)."""

from typing import List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

F64 = npt.NDArray[np.float64]

class InputError(ValueError):
    """Input a user can fix; the message names the file, line and field or the argument."""

def version() -> str: ...
def dataset_noise_seed(seed: int, s: int) -> int:
    """Record seed of sample s of a dataset of spec seed `seed`."""

def make_dataset(spec: str, out: str, threads: Optional[int] = None) -> int:
    """`spibench dataset SPEC --out OUT`; returns the shards written."""

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
        """DMD units (across, down)."""
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
    def values(self, reference: Optional[Trace] = None) -> List[Tuple[str, float]]: ...
    def map(self, name: str) -> F64:
        """x_w (W), g_plus_a, g_minus_a (A), k_plus_a_per_w, k_minus_a_per_w,
        k_plus_stderr_a_per_w, k_minus_stderr_a_per_w (A/W), t_a (A, 4 blocks)."""
    def ledger(self) -> dict: ...

class Kernel:
    grid: Tuple[int, int]
    field_mm: Tuple[float, float]
    units: Tuple[int, int]
    rays: int
    seed: int
    batches: int
    multi_crossing_current_fraction: float
    chart_current_a: float
    multi_crossing_current_a: float
    def csr(
        self, kind: str, index: int
    ) -> Tuple[F64, npt.NDArray[np.uint32], npt.NDArray[np.uint64], Tuple[int, int]]: ...
    def vector(self, kind: str, index: int) -> F64: ...
    def transport_metrics(self, object: F64) -> List[Tuple[str, float, float]]: ...
    def product(
        self, objects: F64, threads: Optional[int] = None, linear: bool = False
    ) -> Tuple[F64, F64]:
        """x_j (W) (N, units) and T (A) (N, 4·units) of each object row (with `linear`, the
        product's linear part)."""

class Acquisition:
    scheme: str
    measurements: int
    pixels: int
    units: Tuple[int, int]
    grid: Tuple[int, int]
    noise_default: bool
    recorded: List[str]
    offset: F64
    coefficients: Tuple[float, float, float, float, float, float]
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
    def reconstruct(
        self, y: F64, threads: Optional[int] = None
    ) -> Tuple[F64, int, str, bool, float, float]: ...
    def time_rust(self, objects: F64, adjoint: bool, repeats: int, threads: Optional[int] = None) -> float:
        """Seconds of the best of `repeats` library calls on the batch, without Python."""

class Dataset:
    seed: int
    def __init__(self, path: str, threads: Optional[int] = None) -> None: ...
    def acquisition(self, scheme: str, ratio: float) -> Acquisition: ...
    def kernel(self) -> Kernel: ...
