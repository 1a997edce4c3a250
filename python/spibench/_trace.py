"""Traces: a traced bench's metrics with standard errors, per-unit maps and flux ledger."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np

from . import _spibench
from ._checks import F64
from ._spibench import Arm

#: The metrics every trace records (name, unit).
METRICS = (
    ("k_plus", "A/W"),
    ("k_minus", "A/W"),
    ("k_prime", "A/W"),
    ("imbalance", "1"),
    ("b_plus", "A"),
    ("b_minus", "A"),
    ("b_minus_minus_b_plus", "A"),
    ("power_plus_w", "W"),
    ("power_minus_w", "W"),
    ("leak_plus", "1"),
    ("leak_minus", "1"),
    ("x_total_w", "W"),
)

#: The arms in index order (0 = +, 1 = −), as every per-arm axis of the package.
ARMS = (Arm.Plus, Arm.Minus)


@dataclass(frozen=True)
class Metric:
    """A traced number with its standard error (unit in :data:`METRICS`)."""

    value: float
    stderr: float


class Trace:
    """A traced bench: metrics with standard errors, per-unit maps and the flux ledger."""

    def __init__(self, inner: "_spibench.Trace"):
        self._t = inner

    @property
    def rays(self) -> int:
        """Lamp rays traced."""
        return self._t.rays

    @property
    def seed(self) -> int:
        """Seed of the trace."""
        return self._t.seed

    def values(self, reference: Optional["Trace"] = None) -> Dict[str, float]:
        """The numbers ``spibench sweep`` records for this bench against ``reference`` (traced
        with the same rays and seed: common random numbers): per metric NAME, NAME_stderr,
        NAME_diff, NAME_diff_stderr (paired), then cmrr_db and arrivals."""
        return dict(self._t.values(None if reference is None else reference._t))

    @property
    def metrics(self) -> Dict[str, Metric]:
        """Each metric of :data:`METRICS` with its standard error."""
        v = self.values()
        return {n: Metric(v[n], v[n + "_stderr"]) for n, _ in METRICS if n in v}

    def diff(self, reference: "Trace") -> Dict[str, Metric]:
        """This bench minus ``reference`` per metric, with the paired standard error."""
        v = self.values(reference)
        return {n: Metric(v[n + "_diff"], v[n + "_diff_stderr"]) for n, _ in METRICS if n in v}

    def _units(self, v: F64) -> F64:
        """A per-unit map as (down, across)."""
        return v.reshape(self._t.units)

    def _arms(self, per_arm) -> F64:
        """A per-arm map of each arm, stacked: (2, down, across)."""
        return np.stack([self._units(per_arm(a)) for a in ARMS])

    @property
    def x_w(self) -> F64:
        """Power incident on each DMD unit x_j (W), (down, across)."""
        return self._units(self._t.x_w())

    @property
    def g_a(self) -> F64:
        """Per-unit gains g±_j (A), (2, down, across): arm + then arm −."""
        return self._arms(self._t.g_a)

    @property
    def k_a_per_w(self) -> F64:
        """k±_j = g±_j / x_j (A/W), (2, down, across); 0 where no light reached the unit."""
        return self._arms(self._t.k_a_per_w)

    @property
    def k_stderr_a_per_w(self) -> F64:
        """Standard errors of k±_j (A/W); +inf where unresolved."""
        return self._arms(self._t.k_stderr_a_per_w)

    @property
    def t_a(self) -> F64:
        """T[d][s][j] (A): diode d's current from light first meeting unit j in state s,
        (2, 2, down, across), index 0 = +, 1 = −."""
        return self._t.t_a().reshape((2, 2) + tuple(self._t.units))

    @property
    def ledger(self) -> dict:
        """Where the traced power went (W), per mirror-state world."""
        return self._t.ledger()

    def __repr__(self) -> str:
        m = self.metrics
        return f"Trace(rays={self.rays}, seed={self.seed}, k_prime={m['k_prime'].value:.6g} A/W)"
