"""Does μ drift straight over the day? The test on the descents' own μ, and the warnings
that say what the day model then does (:func:`station.model.compare.joint_fit`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from scipy.special import stdtr  # Student t (no scipy.stats)

from station.model.compare_types import (
    DescentData,
    JointResult,
)

#: the drift is taken to bend when a curvature this unlikely under a straight drift is seen
#: (so a straight-drift day is warned on about one day in a hundred)
BEND_P = 0.01


class DriftBend(NamedTuple):
    """The curvature of μ over the day seen in the descents' own μ (per hour²)."""

    per_hour2: float
    stderr: float
    p: float  # two-sided, against a straight drift
    dof: int


def drift_bend(data: list[DescentData]) -> DriftBend | None:
    """Does μ drift straight? The single fits' μ of the day's descents, regressed on the items
    and a straight and a quadratic drift over the time of day: the quadratic's t-test, its
    variance from the scatter of the descents about that curve (posture and timer both in
    it). None when the day has no degrees of freedom for it (fewer than items + 4 descents)
    or does not span time.

    Why a test of its own, not the joint fit's residuals: a bend of μ is absorbed by each
    descent's own CdA and v0 in the times, so the times' residuals barely show it, while the
    descents' μ line it up against the clock (the sun coming onto the track, μ +0.02/h
    +0.03/h², made the interval miss 0 on 13 of 24 equal-ski days with a straight drift)."""
    items = sorted({d.item for d in data})
    n = len(data)
    dof = n - len(items) - 2
    if dof < 2:
        return None
    t = np.array([d.start_hours for d in data])
    t = t - t.mean()
    if np.ptp(t) <= 0:
        return None
    x = np.zeros((n, len(items) + 2))
    for k, d in enumerate(data):
        x[k, items.index(d.item)] = 1.0
    x[:, -2], x[:, -1] = t, t * t
    y = np.array([d.start_guess[1] for d in data])
    coef, _res, rank, _sv = np.linalg.lstsq(x, y, rcond=None)
    if rank < x.shape[1]:
        return None
    resid = y - x @ coef
    s2 = float(resid @ resid) / dof
    se = math.sqrt(max(float(s2 * np.linalg.inv(x.T @ x)[-1, -1]), 0.0))
    if se <= 0:
        return None
    tval = float(coef[-1]) / se
    return DriftBend(float(coef[-1]), se, float(2.0 * stdtr(dof, -abs(tval))), dof)


def bend_unseen(data: list[DescentData]) -> bool:
    """Too few descents to test the drift's straightness (:func:`drift_bend`), over a day that
    spans time."""
    n_items = len({d.item for d in data})
    return len(data) - n_items - 2 < 2 and len({d.start_hours for d in data}) > 1


def unseen_bend_warning(data: list[DescentData]) -> str:
    """Why a small day is warned although its drift may well be straight: on ABBA the
    items and a straight drift leave no degrees of freedom for the drift's shape, so a bend
    (the sun coming onto the track) goes straight into Δμ, and the interval then held the
    truth on 5–22 % of such days (benchmarks/compare_small_days.py). A straight day and a
    bent one cannot be told apart, so every such day says it."""
    counts = sorted({sum(d.item == it for d in data) for it in {d.item for d in data}})
    n_items = len({d.item for d in data})
    how = (
        f"{counts[0]} descents an item"
        if len(counts) == 1
        else f"{len(data)} descents of {n_items} items"  # unequal counts: two items or more
    )
    return (
        f"drift: with {how} a bend in the drift of μ cannot be seen (that takes "
        f"{n_items + 4} descents); the intervals assume a straight drift"
    )


def bend_warning(bent: DriftBend, res: JointResult) -> str:
    what = (
        "followed by a quadratic drift (the drift line gives its slope at the day's mean time)"
        if res.drift_bend is not None
        else "the comparison assumes a straight drift, so its intervals may miss; ski the "
        "reference more often (ABBA through the day) or compare the parts of the day apart"
    )
    return (
        f"the drift of μ is not straight: it bends by {bent.per_hour2:+.4f} per hour² over "
        f"the day (p = {bent.p:.2g}, from the descents' own μ): {what}"
    )
