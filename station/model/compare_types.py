"""What the day's comparison takes and gives: the descents it fits, the immutable result
(with its JSON form) and the error when the data cannot answer. Apart from the fit, so that the
views, the season store and the planner read the result without the solver."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any, NamedTuple

import numpy as np

from station.model.estimate import Estimate
from station.model.physics import G_STANDARD
from station.model.timer import TIMER_PRECISION_S


class ComparisonStatus(StrEnum):
    """The verdict of the day's joint fit (the strings earlier versions wrote)."""

    OK = "ok"
    POOR_FIT = "poor-fit"  # residuals the timer's precision cannot explain (χ² test)
    NOT_CONVERGED = "not-converged"


@dataclass(frozen=True)
class DescentData:
    """What the joint fit needs of one descent."""

    number: int
    item: str
    group: str  # who skied it: one mean CdA per group
    photocells: tuple[str, ...]
    times_s: np.ndarray  # relative to the first photocell
    start_hours: float  # time of day of the start, hours (unwrapped)
    mass_kg: float
    air_density: float
    wind_ms: float
    start_guess: tuple[float, float, float]  # (cda, mu, v0) from the single fit
    #: the timer's precision its single fit was judged against (station.model.timer)
    timer_sd_s: float = TIMER_PRECISION_S
    #: the gravity its single fit used (the site's: station.model.physics.gravity_for), so
    #: that the day model's μ and the descents' own agree (standard gravity here moved every
    #: item's μ by 1.8e-4 at 47° N, 1700 m)
    gravity_ms2: float = G_STANDARD


class DayInputs(NamedTuple):
    """A day's descents as the comparison sees them (:func:`station.model.compare.collect`)."""

    data: list[DescentData]  # those that enter the joint fit, in order
    excluded: list[tuple[int, str]]  # those left out, with why
    wind_flagged: list[int]  # those with more along-track wind than the limit

    def items(self) -> list[str]:
        """The test items that enter the fit, sorted (for ``--reference`` prefixes)."""
        return sorted({d.item for d in self.data})


@dataclass(frozen=True)
class ItemResult:
    item: str
    descents: tuple[int, ...]
    mu: float
    ci90: tuple[float, float]
    stderr: float
    mu1: float | None = None
    mu1_ci90: tuple[float, float] | None = None
    p_best: float | None = None  # P(this item has the lowest μ); None: not comparable


@dataclass(frozen=True)
class Comparison:
    a: str
    b: str
    delta_mu: float  # μ_a − μ_b
    ci90: tuple[float, float] | None  # None: no comparison possible (see note)
    p_a_faster: float | None  # P(μ_a < μ_b)
    delta_t_s: float  # time a takes minus time b takes over the run
    #: of the Student t that stands for the interval and its tail beyond (the sequential
    #: rule's): the one as wide at 90 %, capped by Satterthwaite's count (Inference)
    dof: float | None = None
    note: str = ""
    #: whether the run order tells the day's drift from this pair's difference (the items
    #: interleave in time and Δμ is not nearly a multiple of the drift): a pair is judged on
    #: its own, so an item skied once at the end does not make A vs B "not separable"
    drift_separable: bool = True
    #: why the interval is not to be trusted for a decision ("": nothing known against it):
    #: the drift cannot be told from this difference, or the joint fit is poor or did not
    #: converge. The sequential decision reads it (station.model.sequential), so the
    #: console, the UI, ``station compare`` and the report give one answer.
    caveat: str = ""


@dataclass(frozen=True)
class DescentEffect:
    """What the day's fit says of one descent."""

    number: int
    cda: float
    v0: float
    dt0_s: float


@dataclass(frozen=True)
class JointResult:
    """The day's comparison: built once by :func:`station.model.compare.joint_fit`, never
    changed after (hand it to the UI thread, the report and the season store as it is)."""

    items: tuple[ItemResult, ...]
    #: skier (group) -> mean CdA with its 90 % interval (interval None: fixed by ``--cda``)
    cda: dict[str, Estimate]
    drift_per_hour: tuple[float, tuple[float, float]] | None
    drift_separable: bool
    comparisons: tuple[Comparison, ...]
    ranking: tuple[str, ...]
    reference: str | None
    dof: int
    sigma_s: float
    typical_v0: float
    posture_sd: float = 0.0  # between-descent SD of CdA, relative (0.01 = 1 %)
    posture_ci90: tuple[float, float] | None = None
    timer_sd_s: float = TIMER_PRECISION_S
    chi2_p: float | None = None
    descents: tuple[DescentEffect, ...] = ()
    excluded: tuple[tuple[int, str], ...] = ()
    wind_flagged: tuple[int, ...] = ()
    warnings: tuple[str, ...] = ()
    status: ComparisonStatus = ComparisonStatus.OK
    message: str = ""
    #: covariance of the items' μ, in the order of ``items`` (the season store joins the days
    #: by it: station.model.season)
    item_cov: tuple[tuple[float, ...], ...] = ()
    #: the gravity the day was computed with (m/s²): its descents' (the median, when they
    #: differ, which a warning then says)
    gravity_ms2: float = G_STANDARD
    #: the drift's curvature (μ per hour², with its 90 % interval) when the day's drift bends
    #: and is followed by a quadratic (:func:`station.model.compare_drift.drift_bend`); None:
    #: straight
    drift_bend: tuple[float, tuple[float, float]] | None = None

    def item(self, name: str) -> ItemResult:
        """The result of the item called ``name``."""
        return next(i for i in self.items if i.item == name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "status": self.status.value,
            "message": self.message,
            "items": [
                {
                    "item": i.item,
                    "descents": list(i.descents),
                    "mu": i.mu,
                    "ci90": list(i.ci90),
                    "stderr": i.stderr,
                    "p_best": i.p_best,
                    **({"mu1": i.mu1} if i.mu1 is not None else {}),
                    **({"mu1_ci90": list(i.mu1_ci90)} if i.mu1_ci90 is not None else {}),
                }
                for i in self.items
            ],
            "cda": {
                g: {"value": e.value, "ci90": list(e.ci90) if e.ci90 else None}
                for g, e in self.cda.items()
            },
            "posture_sd_pct": 100.0 * self.posture_sd,
            "posture_ci90_pct": (
                [100.0 * self.posture_ci90[0], 100.0 * self.posture_ci90[1]]
                if self.posture_ci90
                else None
            ),
            "drift": (
                {
                    "mu_per_hour": self.drift_per_hour[0],
                    "ci90": list(self.drift_per_hour[1]),
                    "separable": self.drift_separable,
                    **(
                        {
                            "per_hour2": self.drift_bend[0],
                            "per_hour2_ci90": list(self.drift_bend[1]),
                        }
                        if self.drift_bend
                        else {}
                    ),
                }
                if self.drift_per_hour
                else None
            ),
            "comparisons": [
                {
                    "a": c.a,
                    "b": c.b,
                    "delta_mu": c.delta_mu,
                    "ci90": list(c.ci90) if c.ci90 else None,
                    "p_a_faster": c.p_a_faster,
                    "delta_t_s": c.delta_t_s,
                    "dof": c.dof,
                    "note": c.note,
                    "drift_separable": c.drift_separable,
                    "caveat": c.caveat,
                }
                for c in self.comparisons
            ],
            "ranking": list(self.ranking),
            "reference": self.reference,
            "dof": self.dof,
            "sigma_s": self.sigma_s,
            "timer_sd_s": self.timer_sd_s,
            "chi2_p": self.chi2_p,
            "typical_v0": self.typical_v0,
            "gravity_ms2": self.gravity_ms2,
            "descents": [
                {"descent": d.number, "cda": d.cda, "v0": d.v0, "dt0_s": d.dt0_s}
                for d in self.descents
            ],
            "excluded": [{"descent": n, "reason": r} for n, r in self.excluded],
            "wind_flagged": list(self.wind_flagged),
            "warnings": list(self.warnings),
        }


class CompareError(ValueError):
    """Not enough of the right data to compare."""
