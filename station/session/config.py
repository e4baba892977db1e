"""The station config (YAML): serial port, protocol, survey, channel map, skier, air, descents.

    serial:
      port: /dev/ttyUSB0          # a device, COM3, socket://host:port, loop://, or a pty
      baudrate: 9600
      protocol: alge              # alge | tag | microgate
      bytesize: 8
      parity: N                   # N E O M S
      stopbits: 1                 # 1 | 1.5 | 2
      rtscts: false
      xonxoff: false
    survey: surveys/demo_run.yaml # relative to this file
    photocells:                   # timer channel -> photocell id in the survey
      C0: PC1
      C1: PC2
    skier: {mass_kg: 88, name: A. Skier}
    ski: pair 3                   # optional, into the results
    wax: LF blue
    notes: morning, hard snow
    air: {pressure_hpa: 835, temperature_c: -4, humidity_pct: 70}   # or {density: 1.08}
    descent: {debounce_s: 0.3, timeout_s: null, min_speed_ms: 1.0, pairing: auto}
    items: {12: {ski: A, wax: blue}}   # optional: what the bib on a start names
    fit: {model: constant}        # constant | velocity
    latitude_deg: 46.9            # optional: the site, for local gravity, when the survey
    altitude_m: 1650              #   has none (the survey's, measured on the run, comes first)
    timer: {precision_ms: 0.5}    # optional: SD of one crossing time; default from the
                                  #   resolution the timer states (0.5 for 1 ms and finer)

Unknown keys, wrong types and numbers that are not finite or outside a physical range (the
``RANGES`` below) are one clear line naming the file, line and key. A range is wide enough for
any real test day and narrow enough to catch a typo or a wrong unit (``mass_kg: 885``,
``pressure_hpa: 101325``); a decimal comma (``72,5``) is read as a decimal mark.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

from station.errors import InputError
from station.files import MAX_YAML, check_regular
from station.limits import PLAUSIBLE
from station.model.air import air_density
from station.timing.assembly import PAIRINGS
from station.timing.wireformats import PARSERS
from station.yamlfile import Section, parse_yaml, read_yaml_text

if TYPE_CHECKING:
    from station.survey.track import Track


PARITIES = {"N", "E", "O", "M", "S"}

#: field -> (lowest, highest, unit): the physically sane range of every number in the config
RANGES: dict[str, tuple[float, float, str]] = {
    "serial.baudrate": (50, 4_000_000, "baud"),
    "skier.mass_kg": PLAUSIBLE["mass_kg"],
    "air.pressure_hpa": PLAUSIBLE["pressure_hpa"],
    "air.temperature_c": PLAUSIBLE["air_temperature_c"],
    "air.humidity_pct": PLAUSIBLE["humidity_pct"],
    "air.density": PLAUSIBLE["air_density"],
    "descent.debounce_s": (0, 5, "s"),  # double triggers of legs and poles: < 0.5 s
    "descent.timeout_s": (1, 3600, "s"),
    "descent.min_speed_ms": (0.1, 20, "m/s"),  # above it every descent would time out
    "latitude_deg": (-90, 90, "°"),  # geodetic, + north: local gravity
    "altitude_m": (-500, 9000, "m"),  # of the run above sea level
    # one crossing time's SD: a photocell's jitter is some 0.4 ms, a hand on a keypad 50 ms
    "timer.precision_ms": (0.01, 100, "ms"),
}

#: a station config's latitude this far from the survey's is worth a line (0.1° moves g by
#: up to 1.7e-4 m/s², μ by ~2e-6: more is a different site, or a sign error)
LATITUDE_MISMATCH_DEG = 0.1


def _ranged(sec: Section, key: str, default=None, *, required: bool = False, kind=float):
    lo, hi, unit = RANGES[sec.field(key)]
    return sec.number(key, lo, hi, default, unit=unit, required=required, kind=kind)


@dataclass(frozen=True)
class SerialConfig:
    port: str
    protocol: str
    baudrate: int = 9600
    bytesize: int = 8
    parity: str = "N"
    stopbits: float = 1
    rtscts: bool = False
    xonxoff: bool = False


@dataclass(frozen=True)
class DescentConfig:
    debounce_s: float = 0.3
    timeout_s: float | None = None
    min_speed_ms: float = 1.0
    pairing: str = "auto"  # auto | bib | order (station.timing.assembly)


@dataclass(frozen=True)
class AirConfig:
    """The air of the day as the config gives it: measured pressure, temperature and humidity
    (the density computed from them), or a density alone. The metadata of a descent may give
    its own pressure and temperature later (:meth:`station.session.day.Day.density_for`)."""

    density: float  # kg/m³, given or computed
    pressure_hpa: float | None = None  # None: the density was given
    temperature_c: float | None = None
    humidity_pct: float | None = None

    @property
    def measured(self) -> bool:
        """Given as pressure, temperature (and humidity) rather than as a density."""
        return self.pressure_hpa is not None

    def given(self) -> list[tuple[str, float]]:
        """The measured values as the config names them, in its order (none for a density)."""
        values = [("pressure_hpa", self.pressure_hpa), ("temperature_c", self.temperature_c),
                  ("humidity_pct", self.humidity_pct)]  # fmt: skip
        return [(k, v) for k, v in values if v is not None]


@dataclass
class StationConfig:
    path: str
    serial: SerialConfig
    survey_path: str
    channels: dict[str, str]
    mass_kg: float
    air: AirConfig
    descent: DescentConfig = field(default_factory=DescentConfig)
    model: str = "constant"
    metadata: dict[str, str] = field(default_factory=dict)
    text: str = ""
    items: dict[str, dict[str, str]] = field(default_factory=dict)  # bib -> ski, wax, …
    #: the site, for local gravity when the survey has no latitude_deg / altitude_m
    latitude_deg: float | None = None
    altitude_m: float | None = None
    #: the timer's precision (s) as the config states it (``timer: {precision_ms: …}``); None:
    #: from the resolution the timer states (:func:`station.model.timer.precision_from_resolution`)
    timer_precision_s: float | None = None
    #: the season store the session is added to when its recording ends (``store:``, a path
    #: or a postgresql:// URL; None: none, unless $STATION_STORE names one)
    store: str | None = None

    @property
    def air_density(self) -> float:
        """ρ (kg/m³) of the config's air, given or computed."""
        return self.air.density


_TOP = {"serial", "survey", "photocells", "skier", "ski", "wax", "notes", "air", "descent", "fit",
        "items", "latitude_deg", "altitude_m", "timer", "store"}  # fmt: skip


def load_config(path: str) -> StationConfig:
    """The station config at ``path``, checked section by section (one clear line naming the
    file, line and key for anything wrong)."""
    text = read_yaml_text(path, "station config")
    data = parse_yaml(text, path)
    top = Section(data, path, "", _TOP)
    # in the order of the file's documentation: with several mistakes, the first is said
    return StationConfig(
        path=path,
        serial=_serial(top),
        survey_path=_survey_path(top),
        channels=_channels(top),
        mass_kg=_ranged(_skier(top), "mass_kg", required=True),
        air=_air(top),
        descent=_descent(top),
        model=_fit_model(top),
        metadata=_metadata(top),
        text=text,
        items=_items(top),
        latitude_deg=_ranged(top, "latitude_deg"),
        altitude_m=_ranged(top, "altitude_m"),
        timer_precision_s=_timer(top),
        store=top.get("store", str) or None,
    )


def _serial(top: Section) -> SerialConfig:
    """``serial:``: the port and how the timer talks on it."""
    path = top.path
    ser = Section(
        top.data.get("serial"),
        path,
        "serial",
        {"port", "baudrate", "protocol", "bytesize", "parity", "stopbits", "rtscts", "xonxoff"},
    )
    if "serial" not in top.data:
        raise InputError("missing required key", path=path, field="serial")
    protocol = ser.get("protocol", str, required=True)
    if protocol not in PARSERS:
        raise ser.error("protocol", f"unknown protocol {protocol!r} ({', '.join(sorted(PARSERS))})")
    parity = ser.get("parity", str, "N")
    if parity not in PARITIES:
        raise ser.error("parity", f"unknown parity {parity!r} (N, E, O, M, S)")
    stopbits = ser.get("stopbits", float, 1.0)
    if stopbits not in (1, 1.5, 2):
        raise ser.error("stopbits", f"stop bits must be 1, 1.5 or 2, got {stopbits!r}")
    bytesize = ser.get("bytesize", int, 8)
    if bytesize not in (5, 6, 7, 8):
        raise ser.error("bytesize", f"byte size must be 5..8, got {bytesize!r}")
    baud = _ranged(ser, "baudrate", 9600, kind=int)
    port = ser.get("port", str, required=True)
    if not port.strip() or "\0" in port or len(port) > 4096:
        raise ser.error("port", f"not a port name: {port[:40]!r}")
    return SerialConfig(
        port=port,
        protocol=protocol,
        baudrate=baud,
        bytesize=bytesize,
        parity=parity,
        stopbits=int(stopbits) if stopbits != 1.5 else 1.5,
        rtscts=ser.get("rtscts", bool, False),
        xonxoff=ser.get("xonxoff", bool, False),
    )


def _survey_path(top: Section) -> str:
    """``survey:``, relative to the config file; a regular file of sane size."""
    path = top.path
    survey = top.get("survey", str, required=True)
    survey_path = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(path)), survey))
    if not os.path.exists(survey_path):
        raise top.error("survey", f"survey file {survey!r} not found")
    try:
        check_regular(survey_path, MAX_YAML, "survey file")
    except InputError as exc:
        raise top.error("survey", f"survey file {survey!r}: {exc.message}") from None
    return survey_path


def _channels(top: Section) -> dict[str, str]:
    """``photocells:``: timer channel -> photocell id, one photocell per channel."""
    path = top.path
    pcs = top.data.get("photocells")
    if not isinstance(pcs, dict) or not pcs:
        raise top.error("photocells", "expected a mapping of timer channel to photocell id")
    channels: dict[str, str] = {}
    for ch, pc in pcs.items():
        if not isinstance(pc, (str, int)) or isinstance(pc, bool):
            raise InputError(
                f"expected a photocell id, got {pc!r}",
                path=path,
                line=pcs.lines.get(ch) if hasattr(pcs, "lines") else None,
                field=f"photocells.{ch}",
            )
        if str(pc) in channels.values():
            first = next(c for c, p in channels.items() if p == str(pc))
            raise InputError(
                f"photocell {pc} is already on channel {first}; one photocell, one channel",
                path=path,
                line=pcs.lines.get(ch) if hasattr(pcs, "lines") else None,
                field=f"photocells.{ch}",
            )
        channels[str(ch)] = str(pc)
    return channels


def _air(top: Section) -> AirConfig:
    """``air:``: a density, or pressure, temperature and humidity (not both)."""
    air_sec = Section(
        top.data.get("air"),
        top.path,
        "air",
        {"pressure_hpa", "temperature_c", "humidity_pct", "density"},
    )
    if air_sec.has("density"):
        if any(air_sec.has(k) for k in ("pressure_hpa", "temperature_c", "humidity_pct")):
            raise air_sec.error(
                "density", "give density or pressure/temperature/humidity, not both"
            )
        return AirConfig(density=_ranged(air_sec, "density"))
    if "air" not in top.data:
        raise InputError(
            "missing required key (air: {pressure_hpa, temperature_c, humidity_pct}); "
            "ρ enters CdA one to one",
            path=top.path,
            field="air",
        )
    pressure = _ranged(air_sec, "pressure_hpa", required=True)
    temperature = _ranged(air_sec, "temperature_c", required=True)
    humidity = _ranged(air_sec, "humidity_pct", 80.0)
    try:
        rho = air_density(pressure, temperature, humidity)
    except ValueError as exc:
        raise air_sec.error("humidity_pct", str(exc)) from None
    return AirConfig(rho, pressure, temperature, humidity)


def _descent(top: Section) -> DescentConfig:
    """``descent:``: how impulses become descents."""
    dsec = Section(
        top.data.get("descent"),
        top.path,
        "descent",
        {"debounce_s", "timeout_s", "min_speed_ms", "pairing"},
    )
    pairing = dsec.get("pairing", str, "auto")
    if pairing not in PAIRINGS:
        raise dsec.error("pairing", f"unknown pairing {pairing!r} ({', '.join(PAIRINGS)})")
    return DescentConfig(
        debounce_s=_ranged(dsec, "debounce_s", 0.3),
        timeout_s=_ranged(dsec, "timeout_s"),
        min_speed_ms=_ranged(dsec, "min_speed_ms", 1.0),
        pairing=pairing,
    )


def _fit_model(top: Section) -> str:
    """``fit: {model: …}``: constant or velocity-dependent friction."""
    fsec = Section(top.data.get("fit"), top.path, "fit", {"model"})
    model = fsec.get("model", str, "constant")
    if model not in ("constant", "velocity"):
        raise fsec.error("model", f"unknown model {model!r} (constant, velocity)")
    return model


def _timer(top: Section) -> float | None:
    """``timer: {precision_ms: …}``: the SD of one crossing time (s); None when not given."""
    tsec = Section(top.data.get("timer"), top.path, "timer", {"precision_ms"})
    precision_ms = _ranged(tsec, "precision_ms")
    return None if precision_ms is None else precision_ms * 1e-3


def _skier(top: Section) -> Section:
    """``skier: {mass_kg: …, name: …}`` (required: the mass enters every fit)."""
    sk = Section(top.data.get("skier"), top.path, "skier", {"mass_kg", "name"})
    if "skier" not in top.data:
        raise InputError("missing required key (skier: {mass_kg: …})", path=top.path, field="skier")
    return sk


def _metadata(top: Section) -> dict[str, str]:
    """The skier's name, ski, wax and notes: the results' metadata until the UI says else."""
    sk = _skier(top)
    metadata = {}
    if sk.has("name"):
        metadata["skier"] = sk.get("name", str)
    for key in ("ski", "wax", "notes"):
        if top.has(key):
            metadata[key] = top.get(key, str)
    return metadata


def site_track(track: Track, config: StationConfig | None) -> tuple[Track, str]:
    """The track with the station config's latitude and altitude where the survey gives none,
    for local gravity (:func:`station.model.physics.gravity_for`); and a warning line ("" for
    none) when both give a latitude and they differ by more than ``LATITUDE_MISMATCH_DEG``.
    The survey's wins, field by field: it was measured on the run; the config's is what a
    station set up for a day on a known site says about it."""
    if config is None:
        return track, ""
    warning = ""
    lat, alt = track.latitude_deg, track.altitude_m
    if lat is None:
        lat = config.latitude_deg
    elif config.latitude_deg is not None and abs(config.latitude_deg - lat) > LATITUDE_MISMATCH_DEG:
        warning = (
            f"latitude_deg: the survey's {lat:.3f}° ({os.path.basename(config.survey_path)}, "
            f"measured on the run) is used for gravity, not the station config's "
            f"{config.latitude_deg:.3f}° ({os.path.basename(config.path)})"
        )
    if alt is None:
        alt = config.altitude_m
    if (lat, alt) == (track.latitude_deg, track.altitude_m):
        return track, warning
    return replace(track, latitude_deg=lat, altitude_m=alt), warning


def _items(top: Section) -> dict[str, dict[str, str]]:
    """``items: {12: {ski: A, wax: blue}}``: the bib on a start names the ski under test."""
    data = top.data.get("items")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise top.error("items", "expected a mapping of bib to {ski: …, wax: …, notes: …}")
    out: dict[str, dict[str, str]] = {}
    for bib, values in data.items():
        key = str(bib).strip()
        if isinstance(bib, bool) or not (key.isascii() and key.isdigit()):
            raise InputError(f"a bib is a number, got {bib!r}", path=top.path,
                             line=data.lines.get(bib) if hasattr(data, "lines") else None,
                             field=f"items.{bib}")  # fmt: skip
        sec = Section(values, top.path, f"items.{key}", {"ski", "wax", "notes", "skier"},
                      line=data.lines.get(bib, 0) if hasattr(data, "lines") else 0)  # fmt: skip
        out[key.lstrip("0") or "0"] = {k: sec.get(k, str) for k in sec.data if sec.has(k)}
    return out
