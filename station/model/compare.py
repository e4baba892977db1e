"""Test-day analysis: which ski or wax glides better, by how much, and how sure.

One joint least-squares fit over the valid descents of a session:

- one CdA per skier shared by all their descents (the posture is the skier's tuck), or fixed
  from a value the user gives;
- one μ per test item (ski or pair id and wax), optionally one μ1 per item;
- one v0 per descent;
- optionally a linear drift of μ over the time of day, shared by all items, so that
  μ(descent) = μ_item + drift·(t − t̄). It is estimated when an item recurs through the day,
  and the comparison is corrected for it.

The exact sensitivities of each descent (:mod:`station.model.physics`) fill one Jacobian; the fit
is the same bounded trust-region search as for one descent. Differences between items come
with linearised 90 % intervals (Student t on the residual degrees of freedom), the probability
that one is faster, and the time they make over the surveyed run. Sharing CdA removes most of
the μ–CdA correlation that limits a single descent, which is what makes Δμ = 0.001 visible.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.special import stdtr, stdtrit  # Student-t cdf and quantile, without scipy.stats

from station.model.fit import TOLERANCES
from station.model.physics import Conditions, Params, StraightRun
from station.survey.track import Track

US_PER_HOUR = 3.6e9


@dataclass(frozen=True)
class DescentData:
    """What the joint fit needs of one descent."""

    number: int
    item: str
    group: str  # who skied it: one CdA per group
    photocells: tuple[str, ...]
    times_s: np.ndarray  # relative to the first photocell
    start_hours: float  # time of day of the start, hours (unwrapped)
    mass_kg: float
    air_density: float
    wind_ms: float
    start_guess: tuple[float, float, float]  # (cda, mu, v0) from the single fit


@dataclass
class ItemResult:
    item: str
    descents: list[int]
    mu: float
    ci90: tuple[float, float]
    stderr: float
    mu1: float | None = None


@dataclass
class Comparison:
    a: str
    b: str
    delta_mu: float  # μ_a − μ_b
    ci90: tuple[float, float]
    p_a_faster: float  # P(μ_a < μ_b)
    delta_t_s: float  # time a takes minus time b takes over the run


@dataclass
class JointResult:
    items: list[ItemResult]
    cda: dict[
        str, tuple[float, tuple[float, float] | None]
    ]  # group -> (value, ci or None if fixed)
    drift_per_hour: tuple[float, tuple[float, float]] | None
    drift_separable: bool
    comparisons: list[Comparison]
    ranking: list[str]
    reference: str | None
    dof: int
    sigma_s: float
    typical_v0: float
    excluded: list[tuple[int, str]] = field(default_factory=list)
    wind_flagged: list[int] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    status: str = "ok"

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": self.status,
            "items": [
                {
                    "item": i.item,
                    "descents": i.descents,
                    "mu": i.mu,
                    "ci90": list(i.ci90),
                    "stderr": i.stderr,
                    **({"mu1": i.mu1} if i.mu1 is not None else {}),
                }
                for i in self.items
            ],
            "cda": {
                g: {"value": v, "ci90": list(c) if c else None} for g, (v, c) in self.cda.items()
            },
            "drift": (
                {
                    "mu_per_hour": self.drift_per_hour[0],
                    "ci90": list(self.drift_per_hour[1]),
                    "separable": self.drift_separable,
                }
                if self.drift_per_hour
                else None
            ),
            "comparisons": [
                {
                    "a": c.a,
                    "b": c.b,
                    "delta_mu": c.delta_mu,
                    "ci90": list(c.ci90),
                    "p_a_faster": c.p_a_faster,
                    "delta_t_s": c.delta_t_s,
                }
                for c in self.comparisons
            ],
            "ranking": self.ranking,
            "reference": self.reference,
            "dof": self.dof,
            "sigma_s": self.sigma_s,
            "typical_v0": self.typical_v0,
            "excluded": [{"descent": n, "reason": r} for n, r in self.excluded],
            "wind_flagged": self.wind_flagged,
            "warnings": self.warnings,
        }


class CompareError(ValueError):
    """Not enough of the right data to compare."""


def joint_fit(
    track: Track,
    data: list[DescentData],
    *,
    cda_fixed: float | None = None,
    model: str = "constant",
    drift: str = "auto",
    reference: str | None = None,
) -> JointResult:
    """Fit all descents at once; ``drift`` is ``auto`` (when an item recurs), ``on`` or ``off``."""
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

    # parameter layout
    n_g = 0 if cda_fixed is not None else len(groups)
    n_i = len(items)
    per_item = 2 if model == "velocity" else 1
    i_mu = n_g
    i_v0 = n_g + n_i * per_item
    i_drift = i_v0 + len(data)
    n_p = i_drift + (1 if use_drift else 0)
    n_res = sum(len(d.times_s) - 1 for d in data)
    dof = n_res - n_p
    if dof < 1:
        raise CompareError(
            f"{n_res} time differences for {n_p} unknowns: too few photocells or descents"
        )

    runs: dict[tuple[str, ...], StraightRun] = {}
    for d in data:
        if d.photocells not in runs:
            xs = np.array([track.photocell(p).x for p in d.photocells])
            runs[d.photocells] = StraightRun(track.profile, xs)

    def unpack(p: np.ndarray, k: int, d: DescentData) -> tuple[Params, float]:
        cda = cda_fixed if cda_fixed is not None else p[groups.index(d.group)]
        ii = items.index(d.item)
        dt_h = d.start_hours - t_mean
        mu = p[i_mu + ii * per_item] + (p[i_drift] * dt_h if use_drift else 0.0)
        mu1 = p[i_mu + ii * per_item + 1] if per_item == 2 else 0.0
        return Params(float(cda), float(mu), float(p[i_v0 + k]), float(mu1)), dt_h

    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def evaluate(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        key = p.tobytes()
        if key in cache:
            return cache[key]
        r = np.empty(n_res)
        jac = np.zeros((n_res, n_p))
        row = 0
        for k, d in enumerate(data):
            par, dt_h = unpack(p, k, d)
            sol = runs[d.photocells].solve(
                par,
                Conditions(d.mass_kg, d.air_density, d.wind_ms),
                n_params=4 if per_item == 2 else 3,
            )
            m = len(d.times_s) - 1
            r[row : row + m] = sol.t[1:] - d.times_s[1:]
            dt = sol.dt_dp[1:, :]
            if cda_fixed is None:
                jac[row : row + m, groups.index(d.group)] = dt[:, 0]
            ii = items.index(d.item)
            jac[row : row + m, i_mu + ii * per_item] = dt[:, 1]
            if per_item == 2:
                jac[row : row + m, i_mu + ii * per_item + 1] = dt[:, 3]
            jac[row : row + m, i_v0 + k] = dt[:, 2]
            if use_drift:
                jac[row : row + m, i_drift] = dt[:, 1] * dt_h
            row += m
        cache.clear()
        cache[key] = (r, jac)
        return r, jac

    # start from the single fits
    x0 = np.zeros(n_p)
    for g_i, g in enumerate(groups[:n_g]):
        x0[g_i] = np.median([d.start_guess[0] for d in data if d.group == g])
    for ii, it in enumerate(items):
        x0[i_mu + ii * per_item] = np.median([d.start_guess[1] for d in data if d.item == it])
    for k, d in enumerate(data):
        x0[i_v0 + k] = d.start_guess[2]
    lower = np.full(n_p, 0.0)
    upper = np.full(n_p, np.inf)
    if use_drift:
        lower[i_drift], upper[i_drift] = -np.inf, np.inf
    scale = np.ones(n_p)
    scale[:n_g] = 0.1
    scale[i_mu:i_v0] = 0.01
    if per_item == 2:
        scale[i_mu + 1 : i_v0 : 2] = 1e-4
    if use_drift:
        scale[i_drift] = 0.001
    res = least_squares(
        lambda p: evaluate(p)[0],
        np.clip(x0, lower, np.where(np.isfinite(upper), upper, x0 + 1)),
        jac=lambda p: evaluate(p)[1],
        bounds=(lower, upper),
        method="trf",
        x_scale=scale,
        **TOLERANCES,
        max_nfev=200,
    )
    p = res.x
    r, jac = evaluate(p)
    sigma2 = float(r @ r) / dof
    cov = np.linalg.pinv(jac.T @ jac) * sigma2
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    q = float(stdtrit(dof, 0.95))

    out_items = []
    for ii, it in enumerate(items):
        j = i_mu + ii * per_item
        out_items.append(
            ItemResult(
                item=it,
                descents=[d.number for d in data if d.item == it],
                mu=float(p[j]),
                ci90=(float(p[j] - q * sd[j]), float(p[j] + q * sd[j])),
                stderr=float(sd[j]),
                mu1=float(p[j + 1]) if per_item == 2 else None,
            )
        )
    cda_out: dict[str, tuple[float, tuple[float, float] | None]] = {}
    for g_i, g in enumerate(groups):
        if cda_fixed is not None:
            cda_out[g] = (cda_fixed, None)
        else:
            cda_out[g] = (float(p[g_i]), (float(p[g_i] - q * sd[g_i]), float(p[g_i] + q * sd[g_i])))

    warnings: list[str] = []
    drift_out = None
    separable = True
    if use_drift:
        drift_out = (
            float(p[i_drift]),
            (float(p[i_drift] - q * sd[i_drift]), float(p[i_drift] + q * sd[i_drift])),
        )
        # can the run order tell drift from item? look at how drift and item μ co-vary
        for ii in range(len(items)):
            j = i_mu + ii * per_item
            c = cov[j, i_drift] / (sd[j] * sd[i_drift]) if sd[j] > 0 and sd[i_drift] > 0 else 1.0
            if abs(c) > 0.9:
                separable = False
        if len(items) >= 2:
            spans = {it: [d.start_hours for d in data if d.item == it] for it in items}
            for a, b in combinations(items, 2):
                if max(spans[a]) < min(spans[b]) or max(spans[b]) < min(spans[a]):
                    separable = False
        if not separable:
            warnings.append(
                "the run order cannot separate drift from item (e.g. all of one item before the "
                "other): the difference between items and the drift explain the times equally "
                "well; interleave the items (ABBA) and repeat the reference through the day"
            )
    elif len(items) >= 2 and drift != "off":
        warnings.append(
            f"no drift estimated: the reference item {ref!r} does not recur; a change of the "
            "snow during the session would show as a difference between items"
        )

    # comparisons, ranking, and what Δμ means in time over the run
    typical_v0 = float(np.median([p[i_v0 + k] for k in range(len(data))]))
    full_ids = tuple(track.photocell_ids)
    run_full = runs.get(full_ids) or StraightRun(
        track.profile, np.array([pc.x for pc in track.photocells])
    )
    mass = float(np.median([d.mass_kg for d in data]))
    rho = float(np.median([d.air_density for d in data]))
    cda_typ = float(np.median([v for v, _ in cda_out.values()]))

    def run_time(mu: float) -> float:
        sol = run_full.solve(
            Params(cda_typ, mu, typical_v0), Conditions(mass, rho), sensitivities=False
        )
        return float(sol.t[-1])

    times = {it.item: run_time(it.mu) for it in out_items}
    comparisons = []
    order = [ref] + [it for it in items if it != ref] if ref else items
    for a, b in combinations(order, 2):
        ja = i_mu + items.index(a) * per_item
        jb = i_mu + items.index(b) * per_item
        delta = float(p[ja] - p[jb])
        var = cov[ja, ja] + cov[jb, jb] - 2 * cov[ja, jb]
        s = math.sqrt(max(var, 0.0))
        prob = float(stdtr(dof, -delta / s)) if s > 0 else (1.0 if delta < 0 else 0.0)
        comparisons.append(
            Comparison(a, b, delta, (delta - q * s, delta + q * s), prob, times[a] - times[b])
        )
    ranking = [it.item for it in sorted(out_items, key=lambda i: i.mu)]
    status = "ok" if res.status > 0 else "not-converged"
    return JointResult(
        items=out_items,
        cda=cda_out,
        drift_per_hour=drift_out,
        drift_separable=separable,
        comparisons=comparisons,
        ranking=ranking,
        reference=ref,
        dof=dof,
        sigma_s=math.sqrt(sigma2),
        typical_v0=typical_v0,
        warnings=warnings,
        status=status,
    )


def format_comparison(res: JointResult, n_desc: int) -> str:
    """The comparison as the terminal shows it (CLI and UI)."""
    lines = [f"joint fit of {n_desc} descents, {len(res.items)} items, {res.dof} dof, "
             f"timing residual {res.sigma_s * 1000:.2f} ms ({res.status})"]  # fmt: skip
    for g, (v, c) in res.cda.items():
        rng = f"[{c[0]:.4f}, {c[1]:.4f}]" if c else "(fixed)"
        lines.append(f"  CdA {g}: {v:.4f} m² {rng}")
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        sep = "" if res.drift_separable else "  NOT SEPARABLE FROM ITEM"
        lines.append(f"  drift of μ: {d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]{sep}")
    lines.append("")
    lines.append(f"{'rank':<5}{'item':<28}{'descents':>9}{'μ':>10}   90 % CI")
    for k, name in enumerate(res.ranking, start=1):
        it = next(i for i in res.items if i.item == name)
        lines.append(f"{k:<5}{it.item:<28}{len(it.descents):>9}{it.mu:>10.5f}   "
                     f"[{it.ci90[0]:.5f}, {it.ci90[1]:.5f}]")  # fmt: skip
    lines.append("")
    for c in res.comparisons:
        lines.append(
            f"{c.a} − {c.b}: Δμ {c.delta_mu:+.5f} [{c.ci90[0]:+.5f}, {c.ci90[1]:+.5f}], "
            f"P({c.a} faster) = {c.p_a_faster:.3f}, "
            f"{c.delta_t_s * 1000:+.1f} ms over the run at v0 {res.typical_v0:.1f} m/s"
        )
    for n, why in res.excluded:
        lines.append(f"  descent {n} left out: {why}")
    return "\n".join(lines)


def item_of(row: Any) -> str:
    """The test item of a descent: ski (or pair id) and wax, as the engineer entered them
    (``row`` is a :class:`station.session.records.ResultRow`)."""
    return item_name(row.ski, row.wax)


def item_name(ski: str | None, wax: str | None) -> str:
    """A test item's name from its ski (or pair id) and wax."""
    ski = str(ski or "").strip()
    wax = str(wax or "").strip()
    if ski and wax:
        return f"{ski} / {wax}"
    return ski or wax or "(no item)"


def collect(
    results: Iterable[Any], wind_limit_ms: float = 1.0
) -> tuple[list[DescentData], list[tuple[int, str]], list[int]]:
    """The descents that enter the comparison, those left out (with why) and those flagged for
    wind, from a day's results (:class:`station.session.analysis.DescentResult`, in order)."""
    data: list[DescentData] = []
    excluded: list[tuple[int, str]] = []
    windy: list[int] = []
    for res in results:
        row, d, f = res.row, res.descent, res.fit
        n = row.descent
        if row.invalid_reason:
            excluded.append((n, f"marked invalid: {row.invalid_reason}"))
            continue
        if f is None:
            why = "; ".join(row.flags[-1:]) if row.status == "error" else ""
            excluded.append((n, f"{row.status}: {why}" if why else str(row.status)))
            continue
        if row.status not in ("ok", "ill-conditioned"):
            excluded.append((n, str(row.status)))
            continue
        if len(d.photocells) < 3:
            excluded.append((n, "fewer than 3 photocells"))
            continue
        wind = float(row.wind_ms or 0.0)
        if abs(wind) > wind_limit_ms:
            windy.append(n)
        e = f.estimates
        guess = (e.get("cda") or 0.25, e.get("mu") or 0.02, e.get("v0") or 3.0)
        data.append(
            DescentData(
                number=n,
                item=item_of(row),
                group=str(row.skier or "skier"),
                photocells=tuple(d.photocells),
                times_s=(np.array(d.times_us) - d.times_us[0]) / 1e6,
                start_hours=d.times_us[0] / US_PER_HOUR,
                mass_kg=float(row.mass_kg),
                air_density=float(row.air_density),
                wind_ms=wind,
                start_guess=(float(guess[0]), float(guess[1]), float(guess[2])),
            )
        )
    return data, excluded, windy
