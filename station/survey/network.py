"""Placing setups that carry no coordinates: a free-network adjustment of a multi-setup survey.

A control network or a long run is surveyed from several setups, and the file often gives no
setup coordinates at all (Leica GSI code blocks ``41``/``42``/``43``): each setup's shots are
known only in its own frame (its station mark at the origin, its circle unoriented). The setups
are tied together by the points several of them observe, and by their station marks when
another setup observes the mark (a setup named ``BP04`` stands on point ``BP04``).

Method (survey-formats.md §3.2, in a least-squares form):

1. Each observation is reduced in its setup's own frame: a vector l = (e, n, h) from the
   station mark to the target, with its precision (:func:`station.survey.polar.reduce_observation`
   from a setup at 0, 0, 0, circle reading as azimuth).
2. Setups with coordinates are fixed. Without any, the first setup is the datum: its mark at
   0, 0, 0 (or the survey YAML's ``default_setup``) and its circle taken as azimuth.
3. Initial values, one setup at a time: a setup that shares two or more points with the setups
   placed so far is rotated and shifted onto them (a two-dimensional Procrustes fit, heights by
   the mean difference). A setup that never shares two points cannot be placed: the reader
   refuses in one line naming the first such setup.
4. Least squares (scipy): unknowns the tie points' E, N, H (a setup's position is its mark's)
   and each free setup's orientation; residuals R(ω)·l + mark − point, each divided by its
   standard deviation. Points seen from one setup only do not constrain and are reduced after.

The result: every setup's position and orientation, the residual RMS of each, and the largest
residual; the observations then reduce from their own placed setup.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

from station.errors import InputError
from station.survey.polar import (
    Observation,
    ObservationSet,
    Precision,
    Setup,
    reduce_observation,
)

#: a residual larger than this (m) after the adjustment is no measurement error: a point id
#: reused for another point, or a wrong reflector height
GROSS_RESIDUAL_M = 0.05


@dataclass(frozen=True)
class SetupPlacement:
    """One setup as the adjustment placed it, with the residuals of its tie observations."""

    station: str
    e: float
    n: float
    h: float
    orientation: float  # radians
    fixed: bool
    ties: int  # tie observations from this setup
    rms_xy_m: float
    rms_h_m: float
    line: int | None


@dataclass(frozen=True)
class NetworkResult:
    """The adjustment: each setup placed, the tie points, the largest residual."""

    setups: list[SetupPlacement]
    tie_points: int
    observations: int
    rms_xy_m: float
    rms_h_m: float
    worst_m: float
    worst_line: int | None
    worst_text: str


@dataclass(frozen=True)
class _Local:
    """An observation reduced in its setup's own frame."""

    setup: int
    point: str
    v: tuple[float, float, float]
    s_xy: float
    s_h: float
    line: int | None


def _local(obs: Observation, setup_index: int, k: float | None, prec: Precision) -> _Local:
    s = obs.setup
    origin = Setup(s.station, instrument_height=s.instrument_height)
    r = reduce_observation(replace(obs, setup=origin), k, prec)
    return _Local(setup_index, obs.point, (r.e, r.n, r.h), r.sigma_xy, r.sigma_h, obs.line)


def _rot(w: float, e: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate local (e, n) by the orientation w (added to the circle reading)."""
    c, s = math.cos(w), math.sin(w)
    return e * c + n * s, -e * s + n * c


def _procrustes(local: np.ndarray, world: np.ndarray) -> tuple[float, np.ndarray]:
    """Orientation w and shift t with world ≈ R(w)·local + t (2-D, no scale)."""
    lc, wc = local.mean(axis=0), world.mean(axis=0)
    a, b = local - lc, world - wc
    # R(w) maps (e, n) to (e cos w + n sin w, −e sin w + n cos w)
    num = float(np.sum(a[:, 1] * b[:, 0] - a[:, 0] * b[:, 1]))
    den = float(np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    w = math.atan2(num, den)
    re, rn = _rot(w, np.array([lc[0]]), np.array([lc[1]]))
    return w, wc - np.array([re[0], rn[0]])


def _needs_network(obs: ObservationSet) -> bool:
    free = [s for s in obs.setups if not s.known]
    return bool(free) and len(obs.setups) > 1


class _Network:
    """The bookkeeping of one adjustment: setups, tie points, local observations."""

    def __init__(self, obs: ObservationSet, path: str, k: float | None, prec: Precision):
        self.path = path
        self.setups = list(obs.setups)
        index = {id(s): i for i, s in enumerate(self.setups)}
        self.local = [
            _local(o, index[id(o.setup)], k, prec) for o in obs.observations if id(o.setup) in index
        ]
        seen: dict[str, set[int]] = {}
        for loc in self.local:
            seen.setdefault(loc.point, set()).add(loc.setup)
        for i, s in enumerate(self.setups):
            seen.setdefault(s.station, set()).add(i)
        self.ties = sorted(p for p, who in seen.items() if len(who) >= 2)
        tie_set = set(self.ties)
        self.tie_obs = [loc for loc in self.local if loc.point in tie_set]

    def initial(self, datum: Setup | None) -> tuple[dict[str, np.ndarray], dict[int, float]]:
        """Place setups one at a time (step 3); raises InputError for one that cannot be."""
        points: dict[str, np.ndarray] = {}
        orient: dict[int, float] = {}
        fixed = [i for i, s in enumerate(self.setups) if s.known]
        if not fixed:
            d = datum or Setup("datum")
            first = self.setups[0]
            self.setups[0] = replace(first, e=d.e, n=d.n, h=d.h, orientation=d.orientation)
            fixed = [0]
        for i in fixed:
            s = self.setups[i]
            orient[i] = s.orientation
            points.setdefault(s.station, np.array([s.e, s.n, s.h]))
            self._add_points(i, points, orient)
        while len(orient) < len(self.setups):
            best, best_n = None, 1
            for i in range(len(self.setups)):
                if i in orient:
                    continue
                n = len(self._common(i, points))
                if n > best_n:
                    best, best_n = i, n
            if best is None:
                self._refuse(orient, points)
            assert best is not None
            self._place(best, points, orient)
        return points, orient

    def _common(self, i: int, points: dict[str, np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
        """(local, world) pairs of setup i's points already placed, its mark included."""
        pairs: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        mark = self.setups[i].station
        if mark in points:
            pairs[mark] = (np.zeros(3), points[mark])
        for loc in self.local:
            if loc.setup == i and loc.point in points and loc.point not in pairs:
                pairs[loc.point] = (np.array(loc.v), points[loc.point])
        return list(pairs.values())

    def _place(self, i: int, points: dict[str, np.ndarray], orient: dict[int, float]) -> None:
        pairs = self._common(i, points)
        local = np.array([p[0] for p in pairs])
        world = np.array([p[1] for p in pairs])
        w, t = _procrustes(local[:, :2], world[:, :2])
        dh = float(np.mean(world[:, 2] - local[:, 2]))
        orient[i] = w
        points.setdefault(self.setups[i].station, np.array([t[0], t[1], dh]))
        self._add_points(i, points, orient)

    def _add_points(self, i: int, points: dict[str, np.ndarray], orient: dict[int, float]) -> None:
        mark = points[self.setups[i].station]
        for loc in self.local:
            if loc.setup == i and loc.point not in points:
                e, n = _rot(orient[i], np.array([loc.v[0]]), np.array([loc.v[1]]))
                points[loc.point] = mark + np.array([e[0], n[0], loc.v[2]])

    def _refuse(self, orient: dict[int, float], points: dict[str, np.ndarray]) -> None:
        i = next(j for j in range(len(self.setups)) if j not in orient)
        s = self.setups[i]
        n = len(self._common(i, points))
        raise InputError(
            f"setup {s.station} has no coordinates and shares {n} point{'s' * (n != 1)} with the "
            "setups placed before it (2 needed): it cannot be placed. Give its coordinates "
            "(WI 84/85/86) or observe two points another setup observes",
            path=self.path,
            line=s.line,
            field=f"setup {s.station}",
        )


class _Problem:
    """The least-squares problem in arrays: residuals R(ω)·l + mark − target, over σ."""

    def __init__(self, net: _Network, fixed: set[int], free_pts: list[str], points0, orient0):
        names = free_pts + [p for p in points0 if p not in set(free_pts)]
        self.index = {p: j for j, p in enumerate(names)}
        self.n_free = len(free_pts)
        self.base = np.array([points0[p] for p in names])
        self.free_setups = [i for i in range(len(net.setups)) if i not in fixed]
        self.w0 = np.array([orient0[i] for i in range(len(net.setups))])
        obs = net.tie_obs
        self.setup = np.array([o.setup for o in obs], dtype=int)
        self.mark = np.array([self.index[net.setups[o.setup].station] for o in obs], dtype=int)
        self.target = np.array([self.index[o.point] for o in obs], dtype=int)
        self.v = np.array([o.v for o in obs], dtype=float).reshape(-1, 3)
        self.s_xy = np.array([o.s_xy for o in obs])
        self.s_h = np.array([o.s_h for o in obs])

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        pos = self.base.copy()
        pos[: self.n_free] = x[: 3 * self.n_free].reshape(-1, 3)
        w = self.w0.copy()
        w[self.free_setups] = x[3 * self.n_free :]
        return pos, w

    def residuals(self, x: np.ndarray) -> np.ndarray:
        pos, w = self.unpack(x)
        ws = w[self.setup]
        c, s = np.cos(ws), np.sin(ws)
        e = self.v[:, 0] * c + self.v[:, 1] * s
        n = -self.v[:, 0] * s + self.v[:, 1] * c
        mark, target = pos[self.mark], pos[self.target]
        return np.concatenate(
            [
                (mark[:, 0] + e - target[:, 0]) / self.s_xy,
                (mark[:, 1] + n - target[:, 1]) / self.s_xy,
                (mark[:, 2] + self.v[:, 2] - target[:, 2]) / self.s_h,
            ]
        )


def place_setups(
    obs: ObservationSet,
    path: str,
    k: float | None = 0.13,
    precision: Precision | None = None,
    datum: Setup | None = None,
) -> tuple[ObservationSet, NetworkResult | None]:
    """Give every setup without coordinates its position and orientation; observations are
    re-pointed to their placed setup. Returns the set unchanged when nothing needs placing."""
    used = {id(o.setup) for o in obs.observations}
    if any(not s.known and id(s) not in used for s in obs.setups):
        # a setup without coordinates and without shots holds nothing to place or reduce
        obs = replace(obs, setups=[s for s in obs.setups if s.known or id(s) in used])
    if not _needs_network(obs):
        return obs, None
    net = _Network(obs, path, k, precision or Precision())
    points0, orient0 = net.initial(datum)
    fixed = {i for i, s in enumerate(net.setups) if s.known}
    if not any(s.known for s in obs.setups):
        fixed = {0}
    fixed_marks = {net.setups[i].station for i in fixed}
    free_pts = [p for p in net.ties if p not in fixed_marks]
    free_pts += [
        s.station for s in net.setups if s.station not in fixed_marks and s.station not in free_pts
    ]
    free_setups = [i for i in range(len(net.setups)) if i not in fixed]
    x0 = np.concatenate(
        [
            np.concatenate([points0[p] for p in free_pts]) if free_pts else np.zeros(0),
            np.array([orient0[i] for i in free_setups]),
        ]
    )
    problem = _Problem(net, fixed, free_pts, points0, orient0)
    x = x0
    if len(net.tie_obs) and len(x0):
        method = "lm" if 3 * len(net.tie_obs) >= len(x0) else "trf"
        x = least_squares(problem.residuals, x0, method=method).x
    pos, w = problem.unpack(x)
    pts = {p: pos[j] for p, j in problem.index.items()}
    orient = {i: float(w[i]) for i in range(len(net.setups))}
    return _apply(obs, net, fixed, pts, orient)


def _apply(
    obs: ObservationSet,
    net: _Network,
    fixed: set[int],
    pts: dict[str, np.ndarray],
    orient: dict[int, float],
) -> tuple[ObservationSet, NetworkResult]:
    """The placed setups, the observations re-pointed to them, and the residual summary."""
    placed: list[Setup] = []
    for i, s in enumerate(net.setups):
        mark = pts[s.station]
        w = (orient[i] + math.pi) % (2 * math.pi) - math.pi
        placed.append(
            replace(s, e=float(mark[0]), n=float(mark[1]), h=float(mark[2]), orientation=w)
        )
    index = {id(s): i for i, s in enumerate(obs.setups)}
    observations = [replace(o, setup=placed[index[id(o.setup)]]) for o in obs.observations]
    res_xy: dict[int, list[float]] = {}
    res_h: dict[int, list[float]] = {}
    worst = (0.0, None, "")
    for loc in net.tie_obs:
        s = placed[loc.setup]
        e, n = _rot(s.orientation, np.array([loc.v[0]]), np.array([loc.v[1]]))
        target = pts[loc.point]
        dxy = math.hypot(s.e + e[0] - target[0], s.n + n[0] - target[1])
        dh = s.h + loc.v[2] - target[2]
        res_xy.setdefault(loc.setup, []).append(dxy)
        res_h.setdefault(loc.setup, []).append(dh)
        size = math.hypot(dxy, dh)
        if size > worst[0]:
            worst = (size, loc.line, f"{loc.point} from setup {s.station}")

    def rms(v: list[float]) -> float:
        return math.sqrt(sum(a * a for a in v) / len(v)) if v else 0.0

    summary = [
        SetupPlacement(
            s.station,
            s.e,
            s.n,
            s.h,
            s.orientation,
            i in fixed,
            len(res_xy.get(i, [])),
            rms(res_xy.get(i, [])),
            rms(res_h.get(i, [])),
            s.line,
        )
        for i, s in enumerate(placed)
    ]
    all_xy = [a for v in res_xy.values() for a in v]
    all_h = [a for v in res_h.values() for a in v]
    result = NetworkResult(
        summary,
        len(net.ties),
        len(net.tie_obs),
        rms(all_xy),
        rms(all_h),
        worst[0],
        worst[1],
        worst[2],
    )
    out = replace(obs, setups=placed, observations=observations, warnings=list(obs.warnings))
    free = sum(1 for p in summary if not p.fixed)
    out.warnings.append(
        f"{free} setup{'s' * (free != 1)} without coordinates placed from {result.tie_points} "
        f"points observed by two or more setups ({result.observations} observations): residual "
        f"RMS {result.rms_xy_m * 1000:.1f} mm horizontal, {result.rms_h_m * 1000:.1f} mm in "
        f"height; largest {result.worst_m * 1000:.1f} mm (line {result.worst_line}, "
        f"{result.worst_text})"
    )
    if result.worst_m > GROSS_RESIDUAL_M:
        out.warnings.append(
            f"the network does not close: {result.worst_text} (line {result.worst_line}) is "
            f"{result.worst_m:.3f} m off; is a point id used for two points, or a height "
            "booked wrong?"
        )
    return out, result
