"""Shared fixtures: small kernels and datasets of the paper bench (12 × 12 object pixels, a few
thousand rays), so that the suite runs in well under two minutes on two cores."""

from __future__ import annotations

import os
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

import spibench

REPO = Path(__file__).resolve().parents[2]
PAPER = REPO / "scenes" / "paper_bench.ron"
FIELD_MM = 7.88
GRID = (12, 12)
KERNEL_RAYS = 8 * 1024


def spibench_binary():
    """The command-line program: $SPIBENCH_BIN, else the workspace's debug or release build."""
    env = os.environ.get("SPIBENCH_BIN")
    if env:
        return env
    for p in (REPO / "target" / "debug" / "spibench", REPO / "target" / "release" / "spibench"):
        if p.exists():
            return str(p)
    return shutil.which("spibench")


def write_png16(path: Path, image: np.ndarray) -> np.ndarray:
    """A 16-bit grey PNG of ``image`` (values in [0, 1]); returns the values it stores."""
    levels = np.round(np.clip(image, 0.0, 1.0) * 65535.0).astype(">u2")
    h, w = levels.shape
    raw = b"".join(b"\x00" + levels[r].tobytes() for r in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        c = struct.pack(">I", len(data)) + kind + data
        return c + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")
    path.write_bytes(png)
    return levels.astype(np.float64) / 65535.0


def paper_text(noise: bool = True, **replace: str) -> str:
    text = PAPER.read_text()
    for old, new in replace.items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    if not noise:
        text = text.rstrip()
        assert text.endswith(")")
        text = text[:-1] + "    run: (noise: false),\n)\n"
    return text


@pytest.fixture(scope="session")
def paper():
    return spibench.Bench.paper()


@pytest.fixture(scope="session")
def kernel(paper):
    return paper.kernel(grid=GRID, field_mm=FIELD_MM, rays=KERNEL_RAYS, seed=3)


def make_spec(dir: Path, bench: Path, schemes, ratios, samples=3, shard=2) -> Path:
    spec = dir / "spec.ron"
    spec.write_text(
        f"""Dataset(
    bench: "{bench}",
    kernel: (rays: {KERNEL_RAYS}, seed: 1, grid_px: ({GRID[1]}, {GRID[0]}), field_mm: ({FIELD_MM}, {FIELD_MM})),
    objects: TestImages(names: ["astronaut", "coffee"], rule: RandomCrop),
    acquisition: (schemes: [{", ".join(schemes)}], ratios: [{", ".join(map(str, ratios))}]),
    seed: 7,
    samples: {samples},
    shard_samples: {shard},
)
"""
    )
    return spec


DATASET_SCHEMES = ["SecondaryComplementaryBalancing", "DoubleArm", "DoubleArmCalibrated", "Traditional"]


@pytest.fixture(scope="session", params=[True, False], ids=["noise_on", "noise_off"])
def dataset(request, tmp_path_factory):
    """A dataset made by the library's `spibench dataset` (noise on and off)."""
    d = tmp_path_factory.mktemp("ds")
    bench = d / "bench.ron"
    bench.write_text(paper_text(noise=request.param))
    spec = make_spec(d, bench, DATASET_SCHEMES, [0.05, 0.1])
    out = d / "out"
    spibench.make_dataset(spec, out)
    return spibench.open_dataset(out), request.param
