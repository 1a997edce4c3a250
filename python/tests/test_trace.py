"""Benches and traces: `bench.set` + `trace` equals `spibench sweep` at that point bit for bit,
with the paired differences sweep reports."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import spibench
from conftest import paper_text, spibench_binary

VAR = "detectors.minus.decenter_mm.x"


def test_bench_basics(paper):
    assert VAR in paper.variables()
    # A field is read back; a rigid-body move (a decenter) is relative and reads 0.
    field = "max_interactions"
    changed = paper.set({field: 150})
    assert changed.get(field) == 150 and paper.get(field) != 150
    assert spibench.Bench.parse(changed.to_ron()).get(field) == 150
    moved = paper.set({VAR: 0.3})
    assert moved.edits == {VAR: 0.3} and moved.get(VAR) == 0.0
    assert moved.to_ron() != paper.to_ron()
    assert paper.check() == (48, 48)


def test_units_are_down_across_everywhere(tmp_path):
    """One axis order for DMD units, numpy's (down, across): the bench's check, a kernel's
    units, a trace's maps, an acquisition's patterns and a reconstruction (a bench of 40 units
    down and 48 across)."""
    bench = spibench.Bench.parse(
        paper_text(**{"units_across: 48, units_down: 48": "units_across: 48, units_down: 40"}),
        tmp_path / "wide.ron",
    )
    assert bench.check() == (40, 48)
    assert bench.trace(rays=2048, seed=1).x_w.shape == (40, 48)
    kernel = bench.kernel(grid=(4, 6), field_mm=(3.0, 4.5), rays=2048, seed=1)
    assert kernel.units == (40, 48) and kernel.grid == (4, 6)
    acq = spibench.Acquisition(kernel, "double_arm", 0.05)
    assert acq.units == (40, 48) and acq.patterns.shape[1:] == (40, 48)
    assert spibench.reconstruct(acq.forward(np.ones(acq.grid)), acq).image.shape == (40, 48)


def test_trace_maps_and_ledger(paper):
    t = paper.trace(rays=4096, seed=1)
    m = t.metrics
    assert set(m) == {n for n, _ in spibench.METRICS}
    assert m["k_prime"].value > 0 and m["k_prime"].stderr > 0
    assert t.x_w.shape == (48, 48)
    assert t.g_a.shape == t.k_a_per_w.shape == t.k_stderr_a_per_w.shape == (2, 48, 48)
    assert t.t_a.shape == (2, 2, 48, 48)
    # k' = (Σ g₊ + Σ g₋) / Σ x.
    assert np.isclose(t.g_a.sum() / t.x_w.sum(), m["k_prime"].value, rtol=1e-9)
    world = t.ledger["world_plus"]
    assert abs(world["residual_w"]) <= 1e-9 * t.ledger["emitted_w"]
    # The same trace on one thread.
    one = paper.trace(rays=4096, seed=1, threads=1)
    a, b = one.values(), t.values()
    assert list(a) == list(b)
    assert np.array_equal(np.array(list(a.values())), np.array(list(b.values())), equal_nan=True)


def test_set_and_trace_equal_sweep(paper, tmp_path):
    exe = spibench_binary()
    if exe is None:
        pytest.skip("the spibench program is not built (cargo build; or set SPIBENCH_BIN)")
    rays, seed = 4096, 2
    subprocess.run(
        [exe, "sweep", "--vary", f"{VAR}=0.0:0.3:2", "--rays", str(rays), "--seed", str(seed),
         "--out", str(tmp_path / "sweep")],
        check=True, capture_output=True,
    )
    rows = json.loads((tmp_path / "sweep" / "summary.json").read_text())["rows"]
    assert len(rows) == 2
    row = rows[1]
    nominal = paper.trace(rays=rays, seed=seed)
    point = paper.set({VAR: 0.3}).trace(rays=rays, seed=seed)
    values = point.values(nominal)
    checked = 0
    for key, v in values.items():
        if key in row and isinstance(row[key], float):
            assert row[key] == v, key
            checked += 1
    assert checked >= 4 * len(spibench.METRICS)
    diff = point.diff(nominal)["b_minus_minus_b_plus"]
    assert diff.value == values["b_minus_minus_b_plus_diff"]
