"""The day as the joint fit sees it: which global parameter sits where (:class:`Layout`) and
the forward model of all its descents at once (:class:`DayModel`, :mod:`station.model.batch`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from station.model.batch import Rows, solve_rows
from station.model.compare_types import (
    CompareError,
    DescentData,
)
from station.model.physics import StraightRun
from station.survey.track import Track


@dataclass(frozen=True)
class Layout:
    """Who is in the day and where each global parameter sits: the skiers' mean CdA, μ (and
    μ1) per item, the drift; v0 and the offset per descent are local."""

    items: list[str]
    groups: list[str]
    counts: dict[str, int]
    ref: str | None
    use_drift: bool
    drift: str
    t_mean: float
    #: the drift bends: a quadratic term after the linear one (column i_drift + 1)
    bend: bool
    n_g: int
    per_item: int
    i_mu: int
    i_drift: int
    n_glob: int
    dof: int

    @classmethod
    def of(cls, data, cda_fixed, model, drift, reference, bend: bool = False) -> Layout:
        if not data:
            raise CompareError("no valid descent to compare")
        items = sorted(
            {d.item for d in data}, key=lambda it: min(x.number for x in data if x.item == it)
        )
        groups = sorted({d.group for d in data})
        if reference is not None and reference not in items:
            raise CompareError(f"reference item {reference!r} is not among {', '.join(items)}")
        counts = {it: sum(d.item == it for d in data) for it in items}
        recurring = [it for it in items if counts[it] >= 2]
        ref = reference or (max(items, key=lambda it: counts[it]) if items else None)
        use_drift = drift == "on" or (drift == "auto" and ref in recurring and len(data) >= 4)
        t_mean = float(np.mean([d.start_hours for d in data]))
        n_d = len(data)
        n_g = 0 if cda_fixed is not None else len(groups)
        per_item = 2 if model == "velocity" else 1
        i_drift = n_g + len(items) * per_item
        bend = bend and use_drift
        n_glob = i_drift + (1 if use_drift else 0) + (1 if bend else 0)
        n_cells = np.array([len(d.times_s) for d in data])
        n_res = int(n_cells.sum())
        n_fixed = n_glob + 2 * n_d  # v0 and offset per descent are fixed effects too
        dof = n_res - n_fixed
        if dof < 1 or np.any(n_cells < 3):
            raise CompareError(
                f"{n_res} times for {n_fixed} unknowns: too few photocells or descents"
            )
        return cls(items, groups, counts, ref, use_drift, drift, t_mean, bend, n_g, per_item,
                   n_g, i_drift, n_glob, dof)  # fmt: skip

    def mu_index(self, item: str) -> int:
        return self.i_mu + self.items.index(item) * self.per_item


class DayModel:
    """The day's descents as arrays (one row per descent, padded to the most photocells) and
    the forward model of all of them at once (:mod:`station.model.batch`)."""

    def __init__(self, track: Track, data: list[DescentData], lay: Layout, cda_fixed) -> None:
        self.data, self.lay, self.cda_fixed = data, lay, cda_fixed
        n_d = self.n_d = len(data)
        n_cells = np.array([len(d.times_s) for d in data])
        n_max = self.n_max = int(n_cells.max())
        self.mask = np.arange(n_max)[None, :] < n_cells[:, None]
        self.times = np.zeros((n_d, n_max))
        for k, d in enumerate(data):
            self.times[k, : n_cells[k]] = d.times_s
        self.col_g = np.array([lay.groups.index(d.group) for d in data])
        self.col_mu = np.array([lay.mu_index(d.item) for d in data])
        self.dth = np.array([d.start_hours - lay.t_mean for d in data])
        self.kk = np.array([d.air_density / d.mass_kg for d in data])
        self.wind = np.array([d.wind_ms for d in data])
        self.grav = np.array([d.gravity_ms2 for d in data])
        self.runs: dict[tuple[str, ...], tuple[StraightRun, np.ndarray]] = {}
        for pcs in {d.photocells for d in data}:
            xs = np.array([track.photocell(p).x for p in pcs])
            idx = np.array([k for k, d in enumerate(data) if d.photocells == pcs])
            self.runs[pcs] = (StraightRun(track.profile, xs), idx)

    def base_cda(self, glob: np.ndarray) -> np.ndarray:
        """Each descent's skier's mean CdA (or the fixed one)."""
        if self.cda_fixed is not None:
            return np.full(self.n_d, self.cda_fixed)
        return glob[self.col_g]

    def evaluate(self, glob: np.ndarray, loc: np.ndarray):
        """Residuals (D, n) and Jacobians of the globals (D, n, G) and locals (D, n, 3)."""
        lay, n_d, n_max = self.lay, self.n_d, self.n_max
        col_g, col_mu, dth, per_item = self.col_g, self.col_mu, self.dth, lay.per_item
        cda = self.base_cda(glob) * np.exp(loc[:, 0])
        mu = glob[col_mu] + (glob[lay.i_drift] * dth if lay.use_drift else 0.0)
        if lay.bend:
            mu = mu + glob[lay.i_drift + 1] * dth * dth
        mu1 = glob[col_mu + 1] if per_item == 2 else np.zeros(n_d)
        r = np.zeros((n_d, n_max))
        a = np.zeros((n_d, n_max, lay.n_glob))
        b = np.zeros((n_d, n_max, 3))
        stopped = np.zeros(n_d, dtype=bool)
        converged = True
        for run, idx in self.runs.values():
            sol = solve_rows(
                run,
                Rows(cda[idx], mu[idx], loc[idx, 1], mu1[idx], self.kk[idx], self.wind[idx],
                     self.grav[idx]),
                n_params=3 + (per_item - 1),
            )  # fmt: skip
            m = sol.t.shape[1]
            r[idx, :m] = sol.t + loc[idx, 2:3] - self.times[idx, :m]
            dt = sol.dt_dp
            if self.cda_fixed is None:
                a[idx, :m, col_g[idx]] = dt[:, :, 0] * np.exp(loc[idx, 0:1])
            a[idx, :m, col_mu[idx]] = dt[:, :, 1]
            if per_item == 2:
                a[idx, :m, col_mu[idx] + 1] = dt[:, :, 3]
            if lay.use_drift:
                a[idx, :m, lay.i_drift] = dt[:, :, 1] * dth[idx, None]
            if lay.bend:
                a[idx, :m, lay.i_drift + 1] = dt[:, :, 1] * (dth[idx] ** 2)[:, None]
            b[idx, :m, 0] = dt[:, :, 0] * cda[idx, None]
            b[idx, :m, 1] = dt[:, :, 2]
            b[idx, :m, 2] = 1.0
            stopped[idx] = sol.stopped
            converged = converged and bool(sol.converged.all())
        r *= self.mask
        a *= self.mask[:, :, None]
        b *= self.mask[:, :, None]
        return r, a, b, stopped, converged

    def start(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The single fits' medians as the start; the lower bounds of the globals."""
        lay, data = self.lay, self.data
        glob = np.zeros(lay.n_glob)
        for g_i, g in enumerate(lay.groups[: lay.n_g]):
            glob[g_i] = np.median([d.start_guess[0] for d in data if d.group == g])
        for ii, it in enumerate(lay.items):
            glob[lay.i_mu + ii * lay.per_item] = np.median(
                [d.start_guess[1] for d in data if d.item == it]
            )
        loc = np.zeros((self.n_d, 3))
        loc[:, 1] = [d.start_guess[2] for d in data]
        lower = np.full(lay.n_glob, -np.inf)
        lower[: lay.n_g] = 1e-3
        lower[lay.i_mu : lay.i_drift : lay.per_item] = 0.0  # μ ≥ 0; μ1, a slope, either sign
        return glob, loc, lower
