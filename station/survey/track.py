"""Track profile y = h(x) along the fall line, and the photocells' positions on it.

Survey points (E, N, H) are projected onto the vertical plane of a best-fit horizontal axis:
x = horizontal distance along the axis, downhill, from the uppermost profile point; y = height.
The profile is a cubic *smoothing* spline weighted by each point's height precision
(``make_splrep``, w = 1/σ, s = n): continuous h, h′ and h″, and no curvature spikes from noisy
points, which an interpolating spline would turn into normal-force errors (survey-formats.md
§4.2). Photocell posts stand beside the track; only their projection onto x is used.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import make_splrep

from station.errors import InputError
from station.survey.load import Survey

Array = np.ndarray

#: a profile point further than this from the spline, in units of its σ, is left out
OUTLIER_SIGMA = 4.0
#: ... and one further than this from a quadratic through its neighbours, before the spline
SCREEN_SIGMA = 5.0
SCREEN_NEIGHBOURS = 3  # on each side
#: more outliers than this fraction of the profile points: it is not a profile of one run
MAX_OUTLIER_FRACTION = 0.2
#: profile points further than this (m) from the fall-line axis are not on the centre line
MAX_LATERAL_M = 5.0
#: gaps between profile points wider than this (m) cannot carry the curvature
MAX_GAP_M = 10.0
#: photocells closer than this (m) to the surveyed ends sit where the spline is least reliable
END_MARGIN_M = 10.0


@dataclass(frozen=True)
class Profile:
    """y = h(x) with its first two derivatives, valid on [x_min, x_max].

    Any smooth function will do: the track's spline, or a closed-form profile in the tests.
    """

    h: Callable[[Array], Array]
    dh: Callable[[Array], Array]
    d2h: Callable[[Array], Array]
    x_min: float
    x_max: float

    def slope_deg(self, x: Array) -> Array:
        """Slope angle in degrees, positive downhill."""
        return -np.degrees(np.arctan(self.dh(x)))

    def curvature(self, x: Array) -> Array:
        """Signed curvature κ = h″/(1 + h′²)^{3/2}; > 0 in a dip (compression), < 0 on a crest."""
        d1 = self.dh(x)
        return self.d2h(x) / (1.0 + d1 * d1) ** 1.5

    def arc_length(self, x0: float, x1: float, step: float = 0.05) -> float:
        """Arc length between x0 and x1 (composite Simpson on a fine grid)."""
        n = max(2, int(math.ceil(abs(x1 - x0) / step)))
        n += n % 2
        x = np.linspace(x0, x1, n + 1)
        f = np.sqrt(1.0 + self.dh(x) ** 2)
        hstep = (x1 - x0) / n
        return float(hstep / 3.0 * (f[0] + f[-1] + 4.0 * f[1:-1:2].sum() + 2.0 * f[2:-1:2].sum()))


@dataclass(frozen=True)
class TrackPhotocell:
    """A photocell on the track: x on the axis, track height and slope there, lateral offset."""

    id: str
    x: float
    y: float
    slope_deg: float
    lateral_m: float


@dataclass(frozen=True)
class ProfilePoint:
    """A surveyed profile point in track coordinates, with its spline residual."""

    id: str
    x: float
    y: float
    sigma: float
    lateral_m: float
    residual_m: float
    used: bool


@dataclass
class Track:
    """The surveyed run: profile spline, photocells, survey QA values and warnings."""

    name: str
    profile: Profile
    photocells: list[TrackPhotocell]
    points: list[ProfilePoint] = field(default_factory=list)
    origin_en: tuple[float, float] = (0.0, 0.0)
    axis_en: tuple[float, float] = (1.0, 0.0)
    residual_rms_m: float = 0.0
    warnings: list[str] = field(default_factory=list)
    source: str = ""

    def photocell(self, pid: str) -> TrackPhotocell:
        for pc in self.photocells:
            if pc.id == pid:
                return pc
        raise KeyError(pid)

    @property
    def photocell_ids(self) -> list[str]:
        return [pc.id for pc in self.photocells]

    def timed_section(self) -> tuple[float, float]:
        """x of the first and last photocell, or the surveyed span without photocells."""
        if self.photocells:
            return self.photocells[0].x, self.photocells[-1].x
        return self.profile.x_min, self.profile.x_max

    @property
    def length_m(self) -> float:
        """Along-track (arc) length of the timed section."""
        a, b = self.timed_section()
        return self.profile.arc_length(a, b)

    @property
    def drop_m(self) -> float:
        """Height difference over the timed section."""
        a, b = self.timed_section()
        return float(self.profile.h(np.array([a]))[0] - self.profile.h(np.array([b]))[0])

    @property
    def azimuth_deg(self) -> float:
        """Azimuth of the downhill axis, degrees clockwise from grid north."""
        ue, un = self.axis_en
        return math.degrees(math.atan2(ue, un)) % 360.0


def _merge_close(x: Array, y: Array, sigma: Array, tol: float = 1e-3) -> tuple[Array, Array, Array]:
    """Points at (almost) the same x become one, the precision-weighted mean."""
    xs, ys, ss = [x[0]], [y[0]], [sigma[0]]
    for xi, yi, si in zip(x[1:], y[1:], sigma[1:], strict=True):
        if xi - xs[-1] < tol:
            w1, w2 = 1.0 / ss[-1] ** 2, 1.0 / si**2
            ys[-1] = (w1 * ys[-1] + w2 * yi) / (w1 + w2)
            xs[-1] = (w1 * xs[-1] + w2 * xi) / (w1 + w2)
            ss[-1] = 1.0 / math.sqrt(w1 + w2)
        else:
            xs.append(xi)
            ys.append(yi)
            ss.append(si)
    return np.array(xs), np.array(ys), np.array(ss)


def screen_outliers(x: Array, y: Array, sigma: Array) -> list[int]:
    """Indices of points that a quadratic through their neighbours does not explain.

    A smoothing spline adds knots until it meets its residual target, so it *follows* a gross
    error (a wrong reflector height) and turns it into a curvature spike instead of leaving it
    as a residual. Each point is therefore first compared with a weighted quadratic through up
    to three neighbours on each side; the worst point beyond SCREEN_SIGMA is removed and the
    check repeated, so one bad point does not condemn its neighbours.
    """
    keep = list(range(len(x)))
    removed: list[int] = []
    while len(keep) >= 2 * SCREEN_NEIGHBOURS + 1:
        worst, worst_z = -1, SCREEN_SIGMA
        for pos, i in enumerate(keep):
            lo = max(0, pos - SCREEN_NEIGHBOURS)
            hi = min(len(keep), pos + SCREEN_NEIGHBOURS + 1)
            nb = [keep[j] for j in range(lo, hi) if j != pos]
            if len(nb) < 4:
                continue
            xn, yn, sn = x[nb], y[nb], sigma[nb]
            coef = np.polyfit(xn - x[i], yn, 2, w=1.0 / sn)
            scale = math.sqrt(sigma[i] ** 2 + float(np.median(sn)) ** 2)
            z = abs(y[i] - coef[-1]) / scale
            if z > worst_z:
                worst, worst_z = i, z
        if worst < 0:
            break
        keep.remove(worst)
        removed.append(worst)
    return removed


def build_track(survey: Survey) -> Track:
    """Project the survey onto the fall line, fit the profile spline, place the photocells."""
    pts = [survey.points[p] for p in survey.profile_ids]
    if len(pts) < 6:
        raise InputError(
            f"only {len(pts)} profile points; at least 6 are needed to fit the track profile",
            path=survey.path,
            field="profile points",
        )
    en = np.array([[p.e, p.n] for p in pts])
    hh = np.array([p.h for p in pts])
    sig = np.array([p.sigma_h for p in pts])
    centre = en.mean(axis=0)
    _, _, vt = np.linalg.svd(en - centre, full_matrices=False)
    u = vt[0]
    proj = (en - centre) @ u
    if np.polyfit(proj, hh, 1)[0] > 0:  # orient the axis downhill
        u = -u
        proj = -proj
    left = np.array([-u[1], u[0]])
    origin = centre + u * proj.min()
    x_all = (en - origin) @ u
    origin = origin + u * x_all.min()
    x_all = (en - origin) @ u
    x_all -= x_all.min()  # exactly 0 at the uppermost point (rounding left ±1e-14)
    lat_all = (en - origin) @ left

    order = np.argsort(x_all)
    ids = [pts[i].point for i in order]
    x, y, s_, lat = x_all[order], hh[order], sig[order], lat_all[order]
    used = np.ones(len(x), dtype=bool)
    warnings = list(survey.warnings)

    def fit(mask: Array):
        xm, ym, sm = _merge_close(x[mask], y[mask], s_[mask])
        if len(xm) < 6:
            raise InputError(
                "fewer than 6 distinct profile points along the fall line",
                path=survey.path,
                field="profile points",
            )
        return make_splrep(xm, ym, w=1.0 / sm, k=3, s=float(len(xm)))

    removed = screen_outliers(x, y, s_)
    if len(removed) > max(2, MAX_OUTLIER_FRACTION * len(x)):
        raise InputError(
            f"{len(removed)} of {len(x)} profile points do not lie on one smooth line along the "
            f"fall line (lateral offsets up to {np.abs(lat).max():.1f} m): this is not a profile "
            "of the run; name the centre-line points with profile_pattern or exclude the others",
            path=survey.path,
            field="profile points",
        )
    for i in removed:
        used[i] = False
    spl = fit(used)
    resid = y - spl(x)
    bad = (np.abs(resid) > OUTLIER_SIGMA * s_) | ~used
    if bad.any():
        for i in np.flatnonzero(bad):
            warnings.append(
                f"profile point {ids[i]} lies {resid[i] * 1000:.0f} mm from the profile "
                f"(> {OUTLIER_SIGMA:.0f}σ = {OUTLIER_SIGMA * s_[i] * 1000:.0f} mm); left out"
            )
        used = ~bad
        spl = fit(used)
        resid = y - spl(x)

    d1 = spl.derivative(1)
    d2 = spl.derivative(2)
    profile = Profile(h=spl, dh=d1, d2h=d2, x_min=float(x[used].min()), x_max=float(x[used].max()))

    off = used & (np.abs(lat) > MAX_LATERAL_M)
    if off.any():
        worst = int(np.argmax(np.where(off, np.abs(lat), 0.0)))
        warnings.append(
            f"{int(off.sum())} profile points lie more than {MAX_LATERAL_M:.0f} m off the "
            f"fall-line axis (largest {lat[worst]:+.1f} m at {ids[worst]}): does the run curve "
            "in plan, or are these not centre-line points?"
        )
    xu = x[used]
    gaps = np.diff(xu)
    for i in np.flatnonzero(gaps > MAX_GAP_M):
        warnings.append(
            f"profile points {gaps[i]:.1f} m apart between x = {xu[i]:.1f} m and "
            f"{xu[i + 1]:.1f} m: too sparse to resolve the curvature there"
        )

    photocells: list[TrackPhotocell] = []
    for pc in survey.photocells:
        pe = np.mean([[survey.points[p].e, survey.points[p].n] for p in pc.points], axis=0)
        px = float((pe - origin) @ u)
        plat = float((pe - origin) @ left)
        if not profile.x_min <= px <= profile.x_max:
            raise InputError(
                f"photocell {pc.id} at x = {px:.2f} m lies outside the surveyed profile "
                f"({profile.x_min:.1f} .. {profile.x_max:.1f} m)",
                path=survey.path,
                line=pc.line,
                field=f"photocells {pc.id}",
            )
        if px - profile.x_min < END_MARGIN_M or profile.x_max - px < END_MARGIN_M:
            warnings.append(
                f"photocell {pc.id} at x = {px:.1f} m is within {END_MARGIN_M:.0f} m of the end "
                "of the surveyed profile, where the spline is least reliable; survey 20-30 m "
                "beyond the first and last photocell"
            )
        xa = np.array([px])
        photocells.append(
            TrackPhotocell(
                id=pc.id,
                x=px,
                y=float(spl(xa)[0]),
                slope_deg=float(profile.slope_deg(xa)[0]),
                lateral_m=plat,
            )
        )
    for a, b in zip(photocells, photocells[1:], strict=False):
        if b.x <= a.x:
            line = next((p.line for p in survey.photocells if p.id == b.id), None)
            raise InputError(
                f"photocell {b.id} (x = {b.x:.2f} m) is not below {a.id} (x = {a.x:.2f} m); "
                "list photocells in order down the run",
                path=survey.path,
                line=line,
                field=f"photocells {b.id}",
            )

    points = [
        ProfilePoint(
            id=ids[i],
            x=float(x[i]),
            y=float(y[i]),
            sigma=float(s_[i]),
            lateral_m=float(lat[i]),
            residual_m=float(resid[i]),
            used=bool(used[i]),
        )
        for i in range(len(x))
    ]
    rms = float(np.sqrt(np.mean(resid[used] ** 2)))
    return Track(
        name=survey.name,
        profile=profile,
        photocells=photocells,
        points=points,
        origin_en=(float(origin[0]), float(origin[1])),
        axis_en=(float(u[0]), float(u[1])),
        residual_rms_m=rms,
        warnings=warnings,
        source=survey.path,
    )
