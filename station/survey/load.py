"""Survey files: a YAML file naming the observations and the photocells, reduced to points.

A survey YAML (documented in ``surveys/README.md``)::

    name: Demo run
    observations: demo_run.gsi        # any observation file (formats.py), relative to this ...
    # setups: [...]                    # ... or the polar observations inline (see README)
    refraction_k: 0.13                 # null: no curvature and refraction correction
    angle_unit: gon                    # of inline observations and orientations
    default_setup: {station: S0, e: 0, n: 0, h: 0, instrument_height: 1.5}
    precision: {angle_arcsec: 3, distance_mm: 2, distance_ppm: 2, target_mm: 5}
    photocells: [PC1, PC2, PC3]        # in order down the run; or {id: PC1, points: [a, b]}
    points: run_points.csv             # and/or coordinates: id,e,n,h[,sigma_h] (coords.py)
    exclude: [BS1]                     # observed points that are neither profile nor photocell
    profile_pattern: "^P"              # optional: only ids matching this are profile points

A point observed more than once (from two setups) is merged into the precision-weighted mean.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field, replace

from station.errors import InputError
from station.survey.formats import (
    FORMAT_NAMES,
    OBSERVATION_FORMATS,
    is_points_csv,
    read_text,
    sniff,
)
from station.survey.network import NetworkResult, place_setups
from station.survey.polar import (
    KnownPoint,
    Observation,
    ObservationSet,
    Precision,
    ReducedPoint,
    Setup,
    reduce_all,
)
from station.yamlfile import LineList, Section, load_yaml

ANGLE_UNITS = {
    "gon": math.pi / 200.0,
    "deg": math.pi / 180.0,
    "mil": 2.0 * math.pi / 6400.0,
    "rad": 1.0,
}


@dataclass(frozen=True)
class PhotocellDef:
    """A photocell as the survey names it: its id and the surveyed point(s) of its posts."""

    id: str
    points: tuple[str, ...]
    line: int | None = None


@dataclass
class Survey:
    """A reduced survey: every observed point, the profile points and the photocells."""

    path: str
    name: str
    points: dict[str, ReducedPoint]
    profile_ids: list[str]
    photocells: list[PhotocellDef]
    known: list[KnownPoint] = field(default_factory=list)
    setups: list[Setup] = field(default_factory=list)
    refraction_k: float | None = 0.13
    warnings: list[str] = field(default_factory=list)
    #: geodetic latitude of the run (degrees, + north), for local gravity; None: not given
    latitude_deg: float | None = None
    #: altitude of the run above sea level (m) when the survey's heights are local; None: the
    #: survey's own heights are above sea level
    altitude_m: float | None = None
    #: the setups placed by a free-network adjustment (setups without coordinates), else None
    network: NetworkResult | None = None
    #: the observation file's format as found from its content ("" for inline observations)
    format: str = ""
    #: a bare observation or coordinate file (no survey YAML, so no photocells)
    bare: bool = False


def parse_angle(value: object, unit: str, where: Section, key: str) -> float:
    """An angle in ``unit`` (gon, deg, mil, rad, or dms as DDD.MMSS) -> radians."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise where.error(key, f"expected an angle as a number, got {value!r}")
    if unit == "dms":
        sign = -1.0 if value < 0 else 1.0
        v = abs(float(value))
        deg = math.floor(v)
        mm = math.floor(round((v - deg) * 100.0, 6))
        ss = round(((v - deg) * 100.0 - mm) * 100.0, 6)
        if mm >= 60 or ss >= 60:
            raise where.error(key, f"{value!r} is not DDD.MMSS")
        return sign * math.radians(deg + mm / 60.0 + ss / 3600.0)
    return float(value) * ANGLE_UNITS[unit]


def _merge(points: list[ReducedPoint]) -> ReducedPoint:
    """Precision-weighted mean of repeated observations of one point."""
    if len(points) == 1:
        return points[0]
    wh = [1.0 / p.sigma_h**2 for p in points]
    wxy = [1.0 / p.sigma_xy**2 for p in points]
    sh, sxy = sum(wh), sum(wxy)
    first = points[0]
    return ReducedPoint(
        point=first.point,
        e=sum(w * p.e for w, p in zip(wxy, points, strict=True)) / sxy,
        n=sum(w * p.n for w, p in zip(wxy, points, strict=True)) / sxy,
        h=sum(w * p.h for w, p in zip(wh, points, strict=True)) / sh,
        sigma_h=1.0 / math.sqrt(sh),
        sigma_xy=1.0 / math.sqrt(sxy),
        horizontal_distance=min(p.horizontal_distance for p in points),
        setup="+".join(sorted({p.setup for p in points})),
        line=first.line,
        instrument_enh=first.instrument_enh,
    )


#: repeated observations of one id closer than this (m), or within 5σ, are the same point
SAME_POINT_M = 0.05


def _group_points(reduced: list[ReducedPoint], warnings: list[str]) -> dict[str, ReducedPoint]:
    """Merge repeated observations of one point id, but only where they agree.

    Surveyors reuse point numbers (the real ertola file uses 111 ids twice, for points tens of
    metres apart). Observations that agree with the first one within max(5 cm, 5σ) are merged
    into their precision-weighted mean; another point under the same id keeps its own identity
    as ``id@line`` and a warning says so.
    """
    clusters: dict[str, list[list[ReducedPoint]]] = {}
    for p in reduced:
        groups = clusters.setdefault(p.point, [])
        for g in groups:
            ref = g[0]
            dxy = math.hypot(p.e - ref.e, p.n - ref.n)
            dh = abs(p.h - ref.h)
            tol_xy = max(SAME_POINT_M, 5 * math.hypot(p.sigma_xy, ref.sigma_xy))
            tol_h = max(SAME_POINT_M, 5 * math.hypot(p.sigma_h, ref.sigma_h))
            if dxy <= tol_xy and dh <= tol_h:
                g.append(p)
                break
        else:
            groups.append([p])
    points: dict[str, ReducedPoint] = {}
    for pid, groups in clusters.items():
        points[pid] = _merge(groups[0])
        for g in groups[1:]:
            first = groups[0][0]
            new_id = f"{pid}@{g[0].line}"
            dist = math.hypot(g[0].e - first.e, g[0].n - first.n)
            warnings.append(
                f"point id {pid} names another point on line {g[0].line}, {dist:.2f} m from the "
                f"one on line {first.line}; kept apart as {new_id}"
            )
            points[new_id] = replace(_merge(g), point=new_id)
    return points


def _setup_from(sec: Section, unit: str, default_name: str) -> Setup:
    return Setup(
        station=sec.get("station", str, default_name),
        e=sec.get("e", float, 0.0),
        n=sec.get("n", float, 0.0),
        h=sec.get("h", float, 0.0),
        instrument_height=sec.get("instrument_height", float, 0.0),
        orientation=(
            parse_angle(sec.data["orientation"], unit, sec, "orientation")
            if sec.has("orientation")
            else 0.0
        ),
        line=getattr(sec.data, "line", None),
    )


_SETUP_KEYS = {"station", "e", "n", "h", "instrument_height", "orientation"}
_OBS_KEYS = {"point", "hz", "zenith", "sd", "hd", "reflector_height"}


def _inline_observations(top: Section, path: str, unit: str) -> ObservationSet:
    setups = top.data["setups"]
    if not isinstance(setups, list) or not setups:
        raise top.error("setups", "expected a list of instrument setups")
    out = ObservationSet()
    for i, raw in enumerate(setups):
        line = setups.lines[i] if isinstance(setups, LineList) else None
        sec = Section(raw, path, f"setups[{i}]", _SETUP_KEYS | {"observations"}, line or 0)
        setup = _setup_from(sec, unit, f"S{i + 1}")
        out.setups.append(setup)
        obs_list = sec.data.get("observations")
        if not isinstance(obs_list, list):
            raise sec.error("observations", "expected a list of observations")
        for j, o in enumerate(obs_list):
            oline = obs_list.lines[j] if isinstance(obs_list, LineList) else None
            osec = Section(o, path, f"setups[{i}].observations[{j}]", _OBS_KEYS, oline or 0)
            point = osec.get("point", str, required=True)
            hz = parse_angle(osec.get("hz", float, required=True), unit, osec, "hz")
            zen = parse_angle(osec.get("zenith", float, required=True), unit, osec, "zenith")
            sd = osec.get("sd", float)
            hd = osec.get("hd", float)
            if sd is None and hd is None:
                raise InputError(
                    "an observation needs sd (slope distance) or hd (horizontal distance)",
                    path=path,
                    line=oline,
                    field=f"setups[{i}].observations[{j}]",
                )
            if not 0.0 < zen < 2.0 * math.pi:
                raise osec.error("zenith", "zenith angle must lie between 0 and 400 gon")
            out.observations.append(
                Observation(
                    point=point,
                    hz=hz,
                    zenith=zen,
                    slope_distance=sd,
                    horizontal_distance=hd,
                    reflector_height=osec.get("reflector_height", float, 0.0),
                    setup=setup,
                    line=oline,
                )
            )
    return out


_TOP_KEYS = {
    "name",
    "observations",
    "setups",
    "refraction_k",
    "angle_unit",
    "default_setup",
    "precision",
    "photocells",
    "exclude",
    "profile_pattern",
    "notes",
    "latitude_deg",
    "altitude_m",
    "points",
}


def _yaml_like(path: str, text: str) -> bool:
    """A survey YAML by name or by its look (a ``key:`` line): its errors are YAML errors."""
    if path.lower().endswith((".yaml", ".yml")):
        return True
    return any(_YAML_KEY.match(line) for line in text.splitlines()[:50])


_YAML_KEY = re.compile(r"^[A-Za-z_][\w-]*\s*:(\s|$)")


def load_survey(path: str) -> Survey:
    """Load a survey: a YAML, or bare any observation file the station reads (no photocells),
    or a bare points CSV. The format is found from the content; an unknown file gets one line
    naming the formats read."""
    text = read_text(path)
    fmt = sniff(text)
    if fmt is not None:
        return _bare(path, fmt.read(text, path, None), [])
    if is_points_csv(text):
        from station.survey.coords import read_points_csv  # only a list of points needs it

        return _bare(path, ObservationSet(format="points CSV"), read_points_csv(path, 0.005))
    if not text.strip():
        raise InputError(f"an empty file: the station reads {FORMAT_NAMES}", path=path)
    if not _yaml_like(path, text):
        raise InputError(f"not a survey file: the station reads {FORMAT_NAMES}", path=path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise InputError(f"not a survey file: the station reads {FORMAT_NAMES}", path=path)
    return _load_yaml_survey(path, data)


def _bare(path: str, obs: ObservationSet, coords: list[ReducedPoint]) -> Survey:
    obs.warnings.extend(_orientation_warnings(obs))
    obs, network = place_setups(obs, path)
    reduced = reduce_all(obs) + coords + _known_points(obs, Precision())
    survey = _assemble(path, os.path.basename(path), obs, reduced, [], [], None, 0.13)
    survey.network = network
    survey.format = obs.format
    survey.bare = True
    return survey


def _orientation_warnings(obs: ObservationSet) -> list[str]:
    """A setup with coordinates and shots but no backsight: its circle is taken as azimuth.
    (A setup without coordinates is oriented by the network adjustment.)"""
    shooting = {id(o.setup) for o in obs.observations}
    return [
        f"setup {s.station} (line {s.line}) has coordinates but no backsight: its horizontal "
        "circle is taken as azimuth"
        for s in obs.setups
        if s.known and not s.oriented and id(s) in shooting
    ]


def _known_points(obs: ObservationSet, precision: Precision) -> list[ReducedPoint]:
    """Points the file gives by coordinates and no setup observes (an SDR ``08`` record, a
    LandXML ``CgPoint``), as points; the coordinates of an observed point or a station are the
    instrument's own result and stay in ``Survey.known`` for checking."""
    observed = {o.point for o in obs.observations} | {s.station for s in obs.setups}
    sigma = precision.target_mm * 1e-3
    return [
        ReducedPoint(
            point=k.point,
            e=k.e,
            n=k.n,
            h=k.h,
            sigma_h=sigma,
            sigma_xy=sigma,
            horizontal_distance=math.inf,
            setup="coordinates",
            line=k.line,
        )
        for k in obs.known
        if k.point not in observed
    ]


def _precision(top: Section, path: str) -> Precision:
    psec = Section(
        top.data.get("precision"),
        path,
        "precision",
        {"angle_arcsec", "distance_mm", "distance_ppm", "target_mm"},
    )
    return Precision(
        # ranges wide enough for any instrument and pole on snow, narrow enough to catch a
        # wrong unit (an angle in degrees, a distance in metres) before it overflows a weight
        angle_arcsec=psec.number("angle_arcsec", 0.01, 600.0, 3.0, unit="″"),
        distance_mm=psec.number("distance_mm", 0.01, 1000.0, 2.0, unit="mm"),
        distance_ppm=psec.number("distance_ppm", 0.0, 1000.0, 2.0, unit="ppm"),
        target_mm=psec.number("target_mm", 0.01, 1000.0, 5.0, unit="mm"),
    )


def _observations(
    top: Section, path: str, unit: str, default_setup: Setup | None
) -> ObservationSet:
    """The survey's observations: a file in any format read, or inline ``setups:``."""
    has_file, has_inline = top.has("observations"), top.has("setups")
    if has_file and has_inline or not (has_file or has_inline or top.has("points")):
        raise InputError(
            "give 'observations: FILE' or inline 'setups:' (not both), and/or 'points: FILE.csv'",
            path=path,
            line=getattr(top.data, "line", None),
            field="observations",
        )
    if has_inline:
        return _inline_observations(top, path, unit)
    if not has_file:
        return ObservationSet()
    obs_path = top.get("observations", str)
    full = os.path.join(os.path.dirname(os.path.abspath(path)), obs_path)
    if not os.path.exists(full):
        raise top.error("observations", f"observation file {obs_path!r} not found")
    text = read_text(full)
    fmt = sniff(text)
    if fmt is None:
        raise top.error(
            "observations",
            f"{obs_path!r} is not an observation file the station reads ({OBSERVATION_FORMATS})",
        )
    return fmt.read(text, full, default_setup)


def _photocells(top: Section, path: str) -> list[PhotocellDef]:
    photocells: list[PhotocellDef] = []
    raw_pcs = top.data.get("photocells") or []
    if not isinstance(raw_pcs, list):
        raise top.error(
            "photocells", "expected a list of photocell point ids, in order down the run"
        )
    for i, item in enumerate(raw_pcs):
        line = raw_pcs.lines[i] if isinstance(raw_pcs, LineList) else None
        if isinstance(item, dict):
            sec = Section(item, path, f"photocells[{i}]", {"id", "points"}, line or 0)
            pid = sec.get("id", str, required=True)
            pts = sec.data.get("points") or [pid]
            if not isinstance(pts, list) or not pts:
                raise sec.error("points", "expected a list of surveyed point ids")
            photocells.append(PhotocellDef(pid, tuple(str(p) for p in pts), line))
        elif isinstance(item, (str, int)) and not isinstance(item, bool):
            photocells.append(PhotocellDef(str(item), (str(item),), line))
        else:
            raise InputError(
                f"expected a point id, got {item!r}", path=path, line=line, field=f"photocells[{i}]"
            )
    seen: set[str] = set()
    for pc in photocells:
        if pc.id in seen:
            raise InputError(
                "photocell listed twice", path=path, line=pc.line, field=f"photocells {pc.id}"
            )
        seen.add(pc.id)
    return photocells


def _selection(top: Section) -> tuple[list[str], re.Pattern[str] | None]:
    """``exclude:`` and ``profile_pattern:``: which observed points are not the profile."""
    exclude = top.data.get("exclude") or []
    if not isinstance(exclude, list):
        raise top.error("exclude", "expected a list of point ids")
    pattern = None
    if top.has("profile_pattern"):
        try:
            pattern = re.compile(top.get("profile_pattern", str))
        except re.error as exc:
            raise top.error("profile_pattern", f"not a regular expression: {exc}") from None
    return [str(e) for e in exclude], pattern


def _site(top: Section) -> tuple[float | None, float | None]:
    """``latitude_deg`` and ``altitude_m``, for local gravity."""
    latitude = top.get("latitude_deg", float)
    if latitude is not None and not (math.isfinite(latitude) and -90.0 <= latitude <= 90.0):
        raise top.error("latitude_deg", f"must lie between -90 and 90 degrees, got {latitude!r}")
    altitude = top.get("altitude_m", float)
    if altitude is not None and not (math.isfinite(altitude) and -500.0 <= altitude <= 9000.0):
        raise top.error("altitude_m", f"must lie between -500 and 9000 m, got {altitude!r}")
    return latitude, altitude


def _check_observed(survey: Survey, obs: ObservationSet, path: str) -> None:
    """Every photocell post must be a point of the survey; say why one is not."""
    for pc in survey.photocells:
        for p in pc.points:
            if p in survey.points:
                continue
            why = ""
            if p in obs.unreduced:
                why = (
                    f" (line {obs.unreduced[p]} of the observations has its angles but no distance)"
                )
            raise InputError(
                f"photocell point {p!r} was never observed in the survey{why}",
                path=path,
                line=pc.line,
                field=f"photocells {pc.id}",
            )


def _load_yaml_survey(path: str, data: object) -> Survey:
    """A survey YAML: observations (any format or inline), points, photocells, site."""
    top = Section(data, path, "", _TOP_KEYS)
    unit = top.get("angle_unit", str, "gon")
    if unit not in ANGLE_UNITS and unit != "dms":
        raise top.error("angle_unit", f"unknown angle unit {unit!r} (gon, deg, dms, mil, rad)")
    k = top.get("refraction_k", float, 0.13) if "refraction_k" in top.data else 0.13
    if "refraction_k" in top.data and top.data["refraction_k"] is None:
        k = None
    precision = _precision(top, path)
    default_setup = None
    if top.has("default_setup"):
        dsec = Section(top.data["default_setup"], path, "default_setup", _SETUP_KEYS)
        default_setup = _setup_from(dsec, unit, "default")
    obs = _observations(top, path, unit, default_setup)
    obs.warnings.extend(_orientation_warnings(obs))
    obs, network = place_setups(obs, path, k, precision, default_setup)
    reduced = reduce_all(obs, k, precision) + _known_points(obs, precision)
    if top.has("points"):
        csv_path = top.get("points", str)
        full = os.path.join(os.path.dirname(os.path.abspath(path)), csv_path)
        if not os.path.exists(full):
            raise top.error("points", f"coordinate file {csv_path!r} not found")
        from station.survey.coords import read_points_csv  # only a survey with points needs it

        reduced += read_points_csv(full, precision.target_mm * 1e-3)
    photocells = _photocells(top, path)
    exclude, pattern = _selection(top)
    latitude, altitude = _site(top)
    name = top.get("name", str, os.path.basename(path))
    survey = _assemble(path, name, obs, reduced, photocells, exclude, pattern, k)
    _check_observed(survey, obs, path)
    survey.latitude_deg = latitude
    survey.altitude_m = altitude
    survey.network = network
    survey.format = obs.format
    return survey


def _assemble(
    path: str,
    name: str,
    obs: ObservationSet,
    reduced: list[ReducedPoint],
    photocells: list[PhotocellDef],
    exclude: list[str],
    pattern: re.Pattern[str] | None,
    k: float | None,
) -> Survey:
    warnings: list[str] = list(obs.warnings)
    points = _group_points(reduced, warnings)
    ambiguous = {pid.split("@")[0] for pid in points if "@" in pid}
    for pc in photocells:
        for p in pc.points:
            if p in ambiguous:
                raise InputError(
                    f"point id {p!r} names different points in the survey; rename them",
                    path=path,
                    line=pc.line,
                    field=f"photocells {pc.id}",
                )
    not_profile = set(exclude) | {p for pc in photocells for p in pc.points}
    not_profile |= {s.station for s in obs.setups}
    profile_ids = []
    for pid, p in points.items():
        if pid in not_profile or (pattern is not None and not pattern.search(pid)):
            continue
        if p.horizontal_distance < 1e-6:
            warnings.append(f"point {pid} (line {p.line}) has no distance; left out of the profile")
            continue
        profile_ids.append(pid)
    return Survey(
        path=path,
        name=name,
        points=points,
        profile_ids=profile_ids,
        photocells=photocells,
        known=obs.known,
        setups=obs.setups,
        refraction_k=k,
        warnings=warnings,
    )
