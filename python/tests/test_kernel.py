"""Object kernels: the sparse matrices give the library's kernel product exactly, and a direct
trace of the same object agrees within the combined standard error."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

import spibench
from conftest import FIELD_MM, paper_text, write_png16

CHROME = {
    "center_on: Elements(group: -1, first: 5, last: 6),": "center_on: Point((0.0, 0.0)),",
    "chrome_od: Table([(350.0, 3.2), (430.0, 3.0), (700.0, 2.8), (1150.0, 2.5)]),":
        "chrome_od: Constant(10.0),",
    "chrome_reflectance: Constant(0.10),": "chrome_reflectance: Constant(0.0),",
}


def test_sparse_matrices_equal_the_kernel_product(kernel):
    x = np.random.default_rng(1).random((3,) + kernel.grid)
    # The matrices hold the product's linear part exactly.
    light = kernel.dmd_light(x, linear=True)
    t = kernel.transport_a(x, linear=True)
    assert light.shape == (3,) + kernel.units
    for n in range(3):
        v = x[n].ravel()
        assert isinstance(kernel.x_w, sp.csr_matrix)
        assert np.array_equal((kernel.x_w @ v + kernel.x0_w).reshape(kernel.units), light[n])
        for d in range(2):
            for s in range(2):
                got = kernel.t_a[d][s] @ v + kernel.t0_a[d, s]
                assert np.array_equal(got.reshape(kernel.units), t[n, d, s])
    # G = T[on] − T[off] entry by entry; the gains of the product to rounding.
    for d in range(2):
        on, off = (d, 1 - d)
        g = kernel.g_a[d] @ x[0].ravel() + kernel.g0_a[d]
        direct = (t[0, d, on] - t[0, d, off]).ravel()
        assert np.allclose(g, direct, rtol=1e-12, atol=1e-12 * np.max(np.abs(direct)))
        assert kernel.g_stderr_a[d].shape == kernel.g_a[d].shape
    assert kernel.c_a.shape == (2, 144) and kernel.c0_a.shape == (2,)
    # The full product adds the light that meets the chart more than once, weighted by every
    # pixel it met instead of the first (docs/object_kernels.md). The bound is the physics':
    # such a path is weighted t_i1·t_i2·… instead of t_i1, which for t in [0, 1] differs by at
    # most t_i1 ≤ 1 times its current; so over every block and unit the two products differ
    # by at most the clear chart's current on such paths (0.24–0.25 % of the chart's current
    # on the paper bench at 96 × 96, 0.47 % for this kernel), whatever the object. Measured:
    # 0.17–0.21 of it for these objects (uniform t: E[t₁(1 − t₂)] = 1/4).
    full = kernel.transport_a(x)
    m = kernel.multi_crossing_current_a
    assert 0 < kernel.multi_crossing_current_fraction < 1
    assert np.isclose(m, kernel.multi_crossing_current_fraction * kernel.chart_current_a,
                      rtol=1e-12)
    # The chart's current is the clear object's T blocks and pattern-independent light (the
    # same tallies, on the same scale: the field covers the lit chart).
    clear = sum(kernel.t_a[d][s].sum() for d in range(2) for s in range(2))
    clear += sum(kernel.c_a[d].sum() for d in range(2))
    assert np.isclose(clear, kernel.chart_current_a, rtol=1e-9), (clear, kernel.chart_current_a)
    for n in range(3):
        moved = np.abs(full[n] - t[n]).sum()
        assert 0 < moved <= m, (n, moved, m)


def test_kernel_agrees_with_a_direct_trace(tmp_path):
    """A block object as an image mask on black chrome, traced directly, against the same
    object through a kernel of the same bench (combined standard error, |z| < 4.5)."""
    grid = (8, 8)
    obj = np.full(grid, 0.25)
    obj[:, :4] = 1.0
    obj[5:, 5:] = 0.0
    png = tmp_path / "object.png"
    stored = write_png16(png, obj)
    image = f'pattern: Image(path: "{png}", width_mm: {FIELD_MM}, height_mm: {FIELD_MM}),'
    direct = spibench.Bench.parse(
        paper_text(**CHROME, **{"pattern: Usaf(min_group: -2, max_group: 7),": image}),
        tmp_path / "direct.ron",
    )
    clear = spibench.Bench.parse(paper_text(**CHROME), tmp_path / "clear.ron")
    rays = 32 * 1024
    k = clear.kernel(grid=grid, field_mm=FIELD_MM, rays=rays, seed=11)
    through = k.transport_metrics(stored)
    traced = direct.trace(rays=rays, seed=12).metrics
    for name in ("x_total_w", "k_plus", "k_minus", "b_plus", "b_minus"):
        a, b = through[name], traced[name]
        se = np.hypot(a.stderr, b.stderr)
        assert se > 0 and abs(a.value - b.value) < 4.5 * se, (name, a, b)
