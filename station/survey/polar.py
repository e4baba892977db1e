"""Polar observations (Hz, zenith angle, distance) -> local coordinates E, N, H with precision.

Reduction used (survey-formats.md §3.2):

    HD = SD·sin Z,   ΔH = SD·cos Z + hi − hr + (1 − k)·HD² / (2R)
    E = E0 + HD·sin(Hz + ω),   N = N0 + HD·cos(Hz + ω),   H = H0 + ΔH

ω is the setup's orientation. Leica instruments record *oriented* circle readings once the
circle was set (WI 25 holds the correction Hz0 − Hz the instrument already applied), so ω
defaults to 0 and WI 25 is kept for the record, not added again: on the real ertola file,
adding it breaks every point of that setup, leaving it out reproduces all of them.

Each point carries a height and a horizontal standard deviation from the instrument's angle
and distance precision and the target's centring on snow, used to weight the profile spline.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from station.errors import InputError

if TYPE_CHECKING:  # a survey of coordinates only never reads GSI
    from station.survey.gsi import GsiBlock

EARTH_RADIUS_M = 6_371_000.0
ARCSEC = math.pi / (180.0 * 3600.0)


@dataclass(frozen=True)
class Precision:
    """Instrument and target precision, used to weight each reduced point."""

    angle_arcsec: float = 3.0
    distance_mm: float = 2.0
    distance_ppm: float = 2.0
    target_mm: float = 5.0  # pole tilt, sinking into snow, surface roughness


@dataclass(frozen=True)
class Setup:
    """An instrument setup: station coordinates, instrument height, circle orientation ω."""

    station: str
    e: float = 0.0
    n: float = 0.0
    h: float = 0.0
    instrument_height: float = 0.0
    orientation: float = 0.0  # radians, added to Hz to give the azimuth
    line: int | None = None
    #: False: the file gives no coordinates for this setup (a GSI code block ``41``/``42``);
    #: it is placed from the points it shares with other setups (:mod:`station.survey.network`)
    known: bool = True
    #: False: a reader whose format records raw circle readings found no backsight for this
    #: setup, so its circle is taken as azimuth (a warning says so)
    oriented: bool = True


@dataclass(frozen=True)
class Observation:
    """One polar observation of a target point from a setup."""

    point: str
    hz: float  # radians
    zenith: float  # radians
    slope_distance: float | None
    horizontal_distance: float | None
    reflector_height: float
    setup: Setup
    instrument_height: float | None = None  # per-block override (GSI-16 files carry WI 88)
    line: int | None = None
    instrument_enh: tuple[float, float, float] | None = None  # the instrument's own 81/82/83


@dataclass(frozen=True)
class KnownPoint:
    """A point given by coordinates (WI 81/82/83 without angles), e.g. a station or control."""

    point: str
    e: float
    n: float
    h: float
    line: int | None = None


@dataclass(frozen=True)
class ReducedPoint:
    """A target reduced to local coordinates, with its precision and provenance."""

    point: str
    e: float
    n: float
    h: float
    sigma_h: float
    sigma_xy: float
    horizontal_distance: float
    setup: str
    line: int | None = None
    instrument_enh: tuple[float, float, float] | None = None


@dataclass
class ObservationSet:
    """What a survey file holds once its blocks are interpreted."""

    setups: list[Setup] = field(default_factory=list)
    observations: list[Observation] = field(default_factory=list)
    known: list[KnownPoint] = field(default_factory=list)
    #: what the reader passed over and the user should know (one line each)
    warnings: list[str] = field(default_factory=list)
    #: observations that could not be reduced (angles without a distance): point id -> line
    unreduced: dict[str, int] = field(default_factory=dict)
    #: the format's name as shown to the user (e.g. "Leica GSI-16")
    format: str = ""

    def replace_setup(self, old: Setup, new: Setup) -> Setup:
        """``new`` in the place of ``old`` among the setups, returned: a reader learns a
        setup's coordinates, heights or orientation after the record that opened it, and a
        :class:`Setup` is frozen. One method for the RW5, GTS-7 and SDR readers, which each
        had it."""
        i = next(i for i, s in enumerate(self.setups) if s is old)
        self.setups[i] = new
        return new

    def warn_unreduced(self, noun: str = "block", why: str = "with angles but no distance") -> None:
        """The one warning every observation reader gives for the shots it could not reduce,
        when there are any, naming the first eight with their lines (a photocell on one of
        them is refused later, naming that line: survey.load). A method, not a function each
        reader guards and appends: the four readers had those lines alike."""
        unreduced = self.unreduced
        if not unreduced:
            return
        shown = ", ".join(f"{pid} (line {line})" for pid, line in list(unreduced.items())[:8])
        more = f" and {len(unreduced) - 8} more" if len(unreduced) > 8 else ""
        n = len(unreduced)
        self.warnings.append(f"{n} {noun}{'s' * (n != 1)} {why} not reduced: {shown}{more}")


def curvature_refraction(hd: float, k: float | None) -> float:
    """Height correction for earth curvature and refraction, (1 − k)·HD²/(2R); 0 if k is None."""
    if k is None:
        return 0.0
    return (1.0 - k) * hd * hd / (2.0 * EARTH_RADIUS_M)


def reduce_observation(
    obs: Observation, k: float | None = 0.13, precision: Precision = Precision()
) -> ReducedPoint:
    """Reduce one observation to E, N, H in the setup's frame."""
    s = obs.setup
    sin_z, cos_z = math.sin(obs.zenith), math.cos(obs.zenith)
    if obs.slope_distance is not None:
        sd = obs.slope_distance
        hd = sd * sin_z
        dv = sd * cos_z
    else:
        hd = float(obs.horizontal_distance or 0.0)
        sd = hd / sin_z if abs(sin_z) > 1e-12 else hd
        dv = hd * cos_z / sin_z if abs(sin_z) > 1e-12 else 0.0
    hi = obs.instrument_height if obs.instrument_height is not None else s.instrument_height
    az = obs.hz + s.orientation
    e = s.e + hd * math.sin(az)
    n = s.n + hd * math.cos(az)
    h = s.h + hi + dv - obs.reflector_height + curvature_refraction(hd, k)
    sigma_sd = (precision.distance_mm + precision.distance_ppm * sd * 1e-3) * 1e-3
    sigma_ang = precision.angle_arcsec * ARCSEC
    tgt = precision.target_mm * 1e-3
    sigma_h = math.sqrt((cos_z * sigma_sd) ** 2 + (sd * sin_z * sigma_ang) ** 2 + tgt**2)
    sigma_xy = math.sqrt((sin_z * sigma_sd) ** 2 + (hd * sigma_ang) ** 2 + tgt**2)
    return ReducedPoint(
        point=obs.point,
        e=e,
        n=n,
        h=h,
        sigma_h=sigma_h,
        sigma_xy=sigma_xy,
        horizontal_distance=hd,
        setup=s.station,
        line=obs.line,
        instrument_enh=obs.instrument_enh,
    )


def _gsi_observation(
    b: GsiBlock, pid: str, setup: Setup, path: str, default_hr: float = 0.0
) -> Observation:
    zenith = b.value("22")
    assert zenith is not None
    if not (0.0 < zenith < math.pi * 2):
        raise InputError(
            "zenith angle must lie between 0 and 400 gon",
            path=path,
            line=b.line,
            field="WI 22 (zenith angle)",
        )
    hr = b.value("87")
    enh = None
    if b.has("81", "82", "83"):
        enh = (b.value("81"), b.value("82"), b.value("83"))
    return Observation(
        point=pid,
        hz=float(b.value("21")),  # type: ignore[arg-type]
        zenith=float(zenith),
        slope_distance=b.value("31"),
        horizontal_distance=b.value("32"),
        reflector_height=default_hr if hr is None else hr,
        instrument_height=b.value("88"),
        setup=setup,
        line=b.line,
        instrument_enh=enh,  # type: ignore[arg-type]
    )


#: code-block values (WI 41) that start a station: 2, and 21 as Leica MS60 instruments write it
STATION_CODES = {"2", "21"}
#: the code-block value whose WI 42 is the default reflector height (mm) of the shots after it
TARGET_HEIGHT_CODE = "3"


def _millimetres(b: GsiBlock, wi: str, path: str, what: str) -> float:
    """A code-block info word (no unit digit) holding millimetres, e.g. ``43....+00001538``."""
    text = b.words[wi].text
    if not text.isdigit():
        raise InputError(
            f"{what} {text!r} is not a number of millimetres",
            path=path,
            line=b.line,
            field=f"WI {wi} ({what})",
        )
    return int(text) / 1000.0


def _code_block_setup(b: GsiBlock, path: str) -> Setup:
    """A station code block: ``41`` (2 or 21), ``42`` station name, ``43`` instrument height."""
    name = b.words["42"].text.lstrip("0") or "0"
    hi = _millimetres(b, "43", path, "instrument height") if "43" in b.words else 0.0
    return Setup(station=name, instrument_height=hi, line=b.line, known=False)


def read_number(raw: str, path: str, line: int | None, field: str) -> float:
    """``raw`` as a finite number, or the :class:`InputError` naming file, line and field.
    Why one function: each text reader (RW5, GTS-7, SDR, LandXML) had these lines, and a
    damaged value must be refused alike whatever format it came in."""
    try:
        v = float(raw)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise InputError(f"{raw!r} is not a number", path=path, line=line, field=field)
    return v


def interpret_gsi(
    blocks: list[GsiBlock], path: str, default_setup: Setup | None = None
) -> ObservationSet:
    """Sort GSI blocks into station setups, polar observations and known points.

    - a block with any of WI 84/85/86 starts a new setup (88 instrument height, 25 recorded);
      right after a code-block setup (below) it gives that setup its coordinates instead;
    - a code block ``41`` of value 2 or 21 with ``42`` (station name), ``43`` (instrument
      height, mm) and optionally ``44`` (reflector height, mm) starts a new setup without
      coordinates, placed later from the points several setups observe; a code block of value
      3 sets the reflector height (``42``, mm) of the shots without WI 87 after it; other code
      blocks (feature codes) are passed over;
    - a block with 21, 22 and 31 or 32 is an observation (87 reflector height, 88 if present
      overrides the setup's instrument height, 81–83 kept as the instrument's own result);
      with 21 and 22 but no distance it cannot be reduced: a warning names its line;
    - a block with 81/82/83 but no angles is a known point;
    - anything else (other code blocks, remarks) is passed over.
    Observations before the first station block belong to ``default_setup`` (the survey YAML's
    ``default_setup``, else a station at 0, 0, 0 with instrument height 0).
    """
    out = ObservationSet(format="Leica GSI")
    setup = default_setup or Setup(station="default")
    out.setups.append(setup)
    default_hr = 0.0  # a code block's reflector height, for shots without WI 87
    for b in blocks:
        pid = b.point_id or f"block{b.line}"
        code = b.words["41"].text.lstrip("0") if "41" in b.words else None
        if b.has("21", "22") and (b.has("31") or b.has("32")):
            out.observations.append(_gsi_observation(b, pid, setup, path, default_hr))
        elif b.has("21", "22"):
            out.unreduced.setdefault(pid, b.line)
        elif b.has("84") or b.has("85") or b.has("86"):
            fresh = not setup.known and not any(o.setup is setup for o in out.observations)
            new = Setup(
                station=setup.station if fresh else pid,
                e=float(b.value("84") or 0.0),
                n=float(b.value("85") or 0.0),
                h=float(b.value("86") or 0.0),
                instrument_height=float(b.value("88") or (setup.instrument_height if fresh else 0)),
                orientation=default_setup.orientation if default_setup else 0.0,
                line=setup.line if fresh else b.line,
            )
            if fresh:
                out.setups[-1] = new
            else:
                out.setups.append(new)
            setup = new
        elif code in STATION_CODES and b.has("42"):
            setup = _code_block_setup(b, path)
            out.setups.append(setup)
            default_hr = _millimetres(b, "44", path, "reflector height") if b.has("44") else 0.0
        elif code == TARGET_HEIGHT_CODE and b.has("42"):
            default_hr = _millimetres(b, "42", path, "reflector height")
        elif b.has("81") or b.has("82") or b.has("83"):
            out.known.append(
                KnownPoint(
                    point=pid,
                    e=float(b.value("81") or 0.0),
                    n=float(b.value("82") or 0.0),
                    h=float(b.value("83") or 0.0),
                    line=b.line,
                )
            )
    first = out.setups[0]
    if not any(o.setup is first for o in out.observations):
        out.setups.remove(first)  # a file that starts with its station block: no such setup
    out.warn_unreduced(why="with angles but no distance (WI 31 or 32)")
    if any(b.gsi16 for b in blocks):
        out.format = "Leica GSI-16"
    elif blocks:
        out.format = "Leica GSI-8"
    return out


def reduce_all(
    obs: ObservationSet, k: float | None = 0.13, precision: Precision = Precision()
) -> list[ReducedPoint]:
    """Reduce every observation, in file order."""
    return [reduce_observation(o, k, precision) for o in obs.observations]
