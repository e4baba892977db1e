"""Track profile y = h(x) along the fall line, and the photocells' positions on it.

Survey points (E, N, H) are projected onto the vertical plane of a best-fit horizontal axis:
x = horizontal distance along the axis, downhill, from the uppermost profile point; y = height.

The profile is a cubic smoothing spline whose smoothing is estimated from the points themselves
(REML, :mod:`station.survey.smoothing`): exact points are nearly interpolated, rough ones (a
prism pole on snow scatters 1–2 cm) properly smoothed; the declared precision only sets the
relative weights and a floor under the scatter used for screening and uncertainty. The points'
estimated scatter is reported.

Gross errors (a reflector height booked 0.1–0.3 m wrong) are screened one point at a time by
their leave-one-out residual in units of the data's own robust scatter (MAD), so one bad point
never condemns its neighbours and a rough but honest survey is never refused. Photocell posts
stand beside the track; only their projection onto x is used, with its survey precision.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from station.errors import InputError
from station.survey.load import Survey
from station.survey.smoothing import SmoothingFit, fit_smoothing_spline

Array = np.ndarray

#: a point whose leave-one-out residual exceeds this many robust standard deviations is a gross
#: error (at 4.5 an honest survey of 400 points loses one point in some 400 surveys)
SCREEN_Z = 4.5
#: more gross errors than this fraction of the points (and more than MIN_REFUSE of them): the
#: points are not one profile
MAX_OUTLIER_FRACTION = 0.2
MIN_REFUSE = 3
#: a scatter about the profile larger than this (m) is not snow roughness: not one profile
MAX_SCATTER_M = 0.25
#: profile points closer than this (m) in x are merged into their precision-weighted mean
MERGE_M = 0.05
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
    #: standard deviation (m) of x from the survey precision of the photocell's post(s)
    sigma_x_m: float = 0.0


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


@dataclass(frozen=True)
class ProfileUncertainty:
    """The profile's uncertainty as perturbations of its spline coefficients.

    Cov(coefficients) = L Lᵀ, L = ``factor`` (m × r): each column is one independent standard
    perturbation of the profile (the smoothing spline's sampling covariance at the scatter
    ``sigma_m``, floored at the declared precision).
    """

    knots: Array
    coef: Array
    factor: Array
    sigma_m: float

    def profile(
        self, delta: Array | None = None, x_min: float = -math.inf, x_max: float = math.inf
    ) -> Profile:
        """The profile with coefficients coef + delta (delta = factor @ e for a standard draw)."""
        from scipy.interpolate import BSpline

        c = self.coef if delta is None else self.coef + delta
        return spline_profile(BSpline(self.knots, c, 3, extrapolate=True), x_min, x_max)


def spline_profile(spl, x_min: float, x_max: float) -> Profile:
    """A Profile from any scipy spline with ``derivative``."""
    return Profile(h=spl, dh=spl.derivative(1), d2h=spl.derivative(2), x_min=x_min, x_max=x_max)


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
    #: the points' scatter about the profile estimated from the points themselves (m)
    scatter_m: float = 0.0
    #: the declared precision of the profile points (RMS σ, m): the floor under scatter_m
    declared_sigma_m: float = 0.0
    #: effective number of parameters of the spline (3 = a parabola, n = interpolation)
    spline_edf: float = 0.0
    #: the profile's uncertainty, for intervals that carry the survey; None for closed forms
    uncertainty: ProfileUncertainty | None = None
    #: geodetic latitude (degrees) and altitude above sea level (m, None: the profile's own
    #: heights are above sea level), for local gravity
    latitude_deg: float | None = None
    altitude_m: float | None = None

    @property
    def mean_height_m(self) -> float:
        """Mean height of the timed section: the altitude for gravity."""
        if self.altitude_m is not None:
            return self.altitude_m
        a, b = self.timed_section()
        return float(np.mean(self.profile.h(np.linspace(a, b, 21))))

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


def _merge_groups(x: Array, tol: float = MERGE_M) -> list[list[int]]:
    """Indices of (sorted) points grouped where consecutive x are closer than ``tol``."""
    groups = [[0]]
    for i in range(1, len(x)):
        if x[i] - x[groups[-1][-1]] < tol:
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


@dataclass(frozen=True)
class ScreenedFit:
    """The smoothing spline after screening, and the groups it left out with their z-scores."""

    fit: SmoothingFit
    keep: Array  # bool per group
    removed: list[tuple[int, float, float]]  # (group, leave-one-out residual m, z)
    scale_m: float  # robust scatter used for the last screening step


def screen_and_fit(xg: Array, yg: Array, sg: Array, max_removed: int) -> ScreenedFit:
    """Fit the spline, then remove the single worst point while its standardised residual
    exceeds SCREEN_Z robust standard deviations, refitting after each removal.

    The scale is the points' own: 1.4826 × the median absolute standardised residual (a gross
    error barely moves the median), floored at the declared precision so that exact points do
    not make millimetre curvature look like gross errors. Each residual is divided by its own
    standard deviation under the smoother, so a spline that partly follows a gross error still
    shows it (25 cm booked wrong leaves some 17 cm), and the ends, which the spline follows
    closely, are not judged by the middle's yardstick. Only the worst point goes each round,
    so its pull on its neighbours is gone before they are judged: no cascade. Stops after
    ``max_removed + 1`` removals (the caller refuses then). The reported deviation is the
    point against the profile of all the others (leave-one-out).
    """
    keep = np.ones(len(xg), dtype=bool)
    removed: list[tuple[int, float, float]] = []
    while True:
        idx = np.flatnonzero(keep)
        fit = fit_smoothing_spline(xg[idx], yg[idx], sg[idx])
        z1 = fit.standardised(yg[idx], 1.0)
        scale = max(1.4826 * float(np.median(np.abs(z1))), fit.sigma_ref)
        z = z1 / scale
        worst = int(np.argmax(np.abs(z)))
        if abs(z[worst]) <= SCREEN_Z or len(removed) > max_removed or len(idx) <= 7:
            return ScreenedFit(fit, keep, removed, scale)
        loo = float(fit.leave_one_out(yg[idx])[worst])
        keep[idx[worst]] = False
        removed.append((int(idx[worst]), loo, float(z[worst])))


@dataclass(frozen=True)
class _Frame:
    """The fall-line frame: origin (E, N) at the uppermost point, downhill axis u, left normal."""

    origin: Array
    u: Array
    left: Array

    def x(self, en: Array) -> Array:
        return (en - self.origin) @ self.u

    def lateral(self, en: Array) -> Array:
        return (en - self.origin) @ self.left


def _fall_line(en: Array, hh: Array) -> _Frame:
    """Step 1: the principal direction of the points' (E, N), oriented downhill, its origin at
    the uppermost point."""
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
    return _Frame(origin, u, left)


@dataclass(frozen=True)
class _Sorted:
    """The profile points along x, and the groups closer than MERGE_M merged."""

    ids: list[str]
    x: Array
    y: Array
    s: Array
    lat: Array
    groups: list[list[int]]
    xg: Array
    yg: Array
    sg: Array

    def named(self, gis: list[int]) -> str:
        names = [f"{self.ids[i]} ({self.lat[i]:+.1f} m lateral)" for gi in gis
                 for i in self.groups[gi]]  # fmt: skip
        more = f" and {len(names) - 8} more" if len(names) > 8 else ""
        return ", ".join(names[:8]) + more


def _sorted_points(survey: Survey, frame: _Frame, pts: list) -> _Sorted:
    """Step 2: the points in track coordinates, sorted by x, near-duplicates merged."""
    en = np.array([[p.e, p.n] for p in pts])
    x_all = frame.x(en)
    x_all -= x_all.min()  # exactly 0 at the uppermost point (rounding left ±1e-14)
    order = np.argsort(x_all, kind="stable")
    x = x_all[order]
    y = np.array([p.h for p in pts])[order]
    s_ = np.array([p.sigma_h for p in pts])[order]
    groups = _merge_groups(x)
    if len(groups) < 6:
        raise InputError(
            "fewer than 6 distinct profile points along the fall line",
            path=survey.path,
            field="profile points",
        )
    wgt = [1.0 / s_[g] ** 2 for g in groups]
    return _Sorted(
        ids=[pts[i].point for i in order],
        x=x,
        y=y,
        s=s_,
        lat=frame.lateral(en)[order],
        groups=groups,
        xg=np.array([np.average(x[g], weights=w) for g, w in zip(groups, wgt, strict=True)]),
        yg=np.array([np.average(y[g], weights=w) for g, w in zip(groups, wgt, strict=True)]),
        sg=np.array([1.0 / math.sqrt(w.sum()) for w in wgt]),
    )


def _screen(survey: Survey, sp: _Sorted, warnings: list[str]) -> tuple[ScreenedFit, Array]:
    """Step 3: fit with gross errors screened; refuse what is not one profile; name each
    point left out. Returns the fit and which points it used."""
    max_removed = max(MIN_REFUSE, int(MAX_OUTLIER_FRACTION * len(sp.groups)))
    sf = screen_and_fit(sp.xg, sp.yg, sp.sg, max_removed)
    fit = sf.fit
    if len(sf.removed) > max_removed:
        worst = [g for g, _, _ in sf.removed]
        raise InputError(
            f"more than {max_removed} of {len(sp.groups)} profile points do not lie on one "
            f"smooth line along the fall line: {sp.named(worst)} lie far off the profile of the "
            f"others (largest lateral offset {np.abs(sp.lat).max():.1f} m); this is not a "
            "profile of the run. Name the centre-line points with profile_pattern or exclude "
            "the others",
            path=survey.path,
            field="profile points",
        )
    if fit.sigma_hat > MAX_SCATTER_M:
        resid = sp.yg[sf.keep] - fit.fitted
        far = list(np.flatnonzero(sf.keep)[np.argsort(-np.abs(resid))[:5]])
        raise InputError(
            f"the profile points scatter {fit.sigma_hat:.2f} m about any smooth line along the "
            f"fall line (snow roughness is centimetres); furthest off: {sp.named(far)}. They do "
            "not lie on one smooth line along the fall line: this is not a profile of the run. "
            "Name the centre-line points with profile_pattern or exclude the others",
            path=survey.path,
            field="profile points",
        )
    used = np.ones(len(sp.x), dtype=bool)
    for gi, loo, z in sf.removed:
        for i in sp.groups[gi]:
            used[i] = False
            warnings.append(
                f"profile point {sp.ids[i]} lies {loo * 1000:+.0f} mm from the profile of the "
                f"other points ({abs(z):.1f}× their scatter {sf.scale_m * 1000:.0f} mm): a "
                "gross error (reflector height?); left out"
            )
    return sf, used


def _coverage_warnings(sp: _Sorted, used: Array, warnings: list[str]) -> None:
    """Step 4: points far off the axis, and gaps too wide for the curvature."""
    lat = sp.lat
    off = used & (np.abs(lat) > MAX_LATERAL_M)
    if off.any():
        worst_i = int(np.argmax(np.where(off, np.abs(lat), 0.0)))
        warnings.append(
            f"{int(off.sum())} profile points lie more than {MAX_LATERAL_M:.0f} m off the "
            f"fall-line axis (largest {lat[worst_i]:+.1f} m at {sp.ids[worst_i]}): does the run "
            "curve in plan, or are these not centre-line points?"
        )
    xu = sp.x[used]
    gaps = np.diff(xu)
    for i in np.flatnonzero(gaps > MAX_GAP_M):
        warnings.append(
            f"profile points {gaps[i]:.1f} m apart between x = {xu[i]:.1f} m and "
            f"{xu[i + 1]:.1f} m: too sparse to resolve the curvature there"
        )


def _place_photocells(
    survey: Survey, frame: _Frame, profile: Profile, warnings: list[str]
) -> list[TrackPhotocell]:
    """Step 5: each photocell's posts projected onto x; inside the profile, in order."""
    photocells: list[TrackPhotocell] = []
    for pc in survey.photocells:
        post = [survey.points[p] for p in pc.points]
        pe = np.mean([[q.e, q.n] for q in post], axis=0)
        sigma_x = math.sqrt(sum(q.sigma_xy**2 for q in post)) / len(post)
        px, plat = float(frame.x(pe)), float(frame.lateral(pe))
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
                y=float(profile.h(xa)[0]),
                slope_deg=float(profile.slope_deg(xa)[0]),
                lateral_m=plat,
                sigma_x_m=sigma_x,
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
    return photocells


def build_track(survey: Survey) -> Track:
    """Project the survey onto the fall line, fit the profile spline, place the photocells."""
    pts = [survey.points[p] for p in survey.profile_ids]
    if len(pts) < 6:
        raise InputError(
            f"only {len(pts)} profile points; at least 6 are needed to fit the track profile",
            path=survey.path,
            field="profile points",
        )
    frame = _fall_line(np.array([[p.e, p.n] for p in pts]), np.array([p.h for p in pts]))
    sp = _sorted_points(survey, frame, pts)
    warnings = list(survey.warnings)
    sf, used = _screen(survey, sp, warnings)
    fit = sf.fit
    spl = fit.spline()
    profile = spline_profile(spl, float(sp.x[used].min()), float(sp.x[used].max()))
    resid = sp.y - spl(sp.x)
    sigma_unc = max(fit.sigma_hat, fit.sigma_ref)
    uncertainty = ProfileUncertainty(
        knots=fit.knots, coef=fit.coef, factor=fit.coef_covariance_factor(sigma_unc),
        sigma_m=sigma_unc,
    )  # fmt: skip
    _coverage_warnings(sp, used, warnings)
    photocells = _place_photocells(survey, frame, profile, warnings)
    points = [
        ProfilePoint(id=sp.ids[i], x=float(sp.x[i]), y=float(sp.y[i]), sigma=float(sp.s[i]),
                     lateral_m=float(sp.lat[i]), residual_m=float(resid[i]), used=bool(used[i]))
        for i in range(len(sp.x))
    ]  # fmt: skip
    return Track(
        name=survey.name,
        profile=profile,
        photocells=photocells,
        points=points,
        origin_en=(float(frame.origin[0]), float(frame.origin[1])),
        axis_en=(float(frame.u[0]), float(frame.u[1])),
        residual_rms_m=float(np.sqrt(np.mean(resid[used] ** 2))),
        warnings=warnings,
        source=survey.path,
        scatter_m=fit.sigma_hat,
        declared_sigma_m=fit.sigma_ref,
        spline_edf=fit.edf,
        uncertainty=uncertainty,
        latitude_deg=survey.latitude_deg,
        altitude_m=survey.altitude_m,
    )
