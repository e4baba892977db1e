"""Reader for Sokkia SDR33 / SDR2x files: fixed-width records → setups, observations, points.

Every record starts with a two-digit type and a two-letter derivation code (``TP`` topography,
``KI`` keyboard input, ``CO`` coordinate program, ``NM`` not measured, ``F1``/``F2`` face);
then fixed-width fields: in SDR33 files point ids and numbers are 16 characters wide, in SDR2x
files ids are 4 and numbers 10 (the ``10`` job record's point-id flag decides, as does an
``SDR33`` header).

- ``00`` header: six flag digits at columns 41–46: angle unit (1 degrees, 2 gon, 3 mil),
  distance unit (1 m, 2 ft), pressure, temperature, order of the plane coordinates (1 N-E,
  2 E-N) and direction of horizontal angles (1 clockwise, 2 counter-clockwise). They are read,
  never assumed: a file whose flags are missing or unknown is refused naming the flag.
- ``02`` station: id, two plane coordinates, height, instrument height (a new setup).
- ``03`` target height, valid for the observations after it.
- ``07`` backsight: station, backsight point, its azimuth, the circle reading on it: the
  setup's orientation ω = azimuth − reading (the azimuth from the coordinates when blank).
- ``08`` coordinates: id, two plane coordinates, height, code (a point given by coordinates).
- ``09`` observation (``F1``/``F2``): station, target, slope distance, zenith angle, horizontal
  angle, code.
- ``01`` instrument: column 51 says how vertical angles are read (1 zenith angle, 2 elevation
  angle from the horizontal, turned into a zenith angle here).
- other records (``06`` scale, ``13`` notes/comments, …) are passed over.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

from station.errors import InputError
from station.survey.gsi import FOOT_M, split_lines
from station.survey.polar import (
    KnownPoint,
    Observation,
    ObservationSet,
    Setup,
    read_number,
)

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")
ANGLE = {
    "1": ("degrees", math.pi / 180.0),
    "2": ("gon", math.pi / 200.0),
    "3": ("mil", 2.0 * math.pi / 6400.0),
}
DISTANCE = {"1": ("m", 1.0), "2": ("ft", FOOT_M)}
ORDER = {"1": "N-E", "2": "E-N"}
DIRECTION = {"1": "clockwise", "2": "counter-clockwise"}


@dataclass(frozen=True)
class SdrUnits:
    """What the ``00`` header's flags say."""

    angle: float  # radians per unit
    distance: float  # metres per unit
    north_first: bool
    clockwise: bool


def _flag(line: str, col: int, table: dict, name: str, path: str, lineno: int) -> object:
    ch = line[col : col + 1]
    if ch not in table:
        known = ", ".join(f"{k} {v[0] if isinstance(v, tuple) else v}" for k, v in table.items())
        raise InputError(
            f"{ch or 'nothing'!r} is not a known {name} flag ({known}); the station does not "
            "guess it",
            path=path,
            line=lineno,
            field=f"00 header column {col + 1} ({name})",
        )
    return table[ch]


def header_units(line: str, path: str, lineno: int) -> SdrUnits:
    """Units and coordinate order from the ``00`` header's flags (columns 41–46)."""
    angle = _flag(line, 40, ANGLE, "angle unit", path, lineno)
    dist = _flag(line, 41, DISTANCE, "distance unit", path, lineno)
    order = _flag(line, 44, ORDER, "coordinate order", path, lineno)
    direction = _flag(line, 45, DIRECTION, "angle direction", path, lineno)
    return SdrUnits(angle[1], dist[1], order == "N-E", direction == "clockwise")  # type: ignore[index]


class _Record:
    """One record cut into its fixed-width fields, each parsed with the record's line."""

    def __init__(self, line: str, lineno: int, path: str, id_w: int, num_w: int):
        self.line, self.lineno, self.path = line, lineno, path
        self.id_w, self.num_w = id_w, num_w
        self.pos = 4

    def ident(self, name: str) -> str:
        raw = self.line[self.pos : self.pos + self.id_w].strip()
        self.pos += self.id_w
        return raw.lstrip("0") or ("0" if raw else "")

    def number(self, name: str, width: int | None = None) -> float | None:
        w = width or self.num_w
        raw = self.line[self.pos : self.pos + w].strip()
        self.pos += w
        if not raw:
            return None
        return read_number(raw, self.path, self.lineno, f"{self.line[:4]} {name}")

    def text(self, width: int) -> str:
        raw = self.line[self.pos : self.pos + width].strip()
        self.pos += width
        return raw

    def need(self, value: float | None, name: str) -> float:
        if value is None:
            raise InputError(
                "missing", path=self.path, line=self.lineno, field=f"{self.line[:4]} {name}"
            )
        return value


class _Reader:
    """The state of one SDR file being read: units, current setup, target height."""

    def __init__(self, path: str):
        self.path = path
        self.units: SdrUnits | None = None
        self.id_w, self.num_w = 16, 16
        self.out = ObservationSet(format="Sokkia SDR")
        self.setup: Setup | None = None
        self.target_h = 0.0
        self.coords: dict[str, KnownPoint] = {}
        self.elevation = False  # vertical angles as elevations (01 record), not zenith angles

    def rec(self, line: str, lineno: int) -> _Record:
        return _Record(line, lineno, self.path, self.id_w, self.num_w)

    def need_units(self, lineno: int) -> SdrUnits:
        if self.units is None:
            raise InputError(
                "a record before the 00 header: units unknown",
                path=self.path,
                line=lineno,
                field="00 header",
            )
        return self.units

    def plane(self, r: _Record) -> tuple[float | None, float | None, float | None]:
        u = self.need_units(r.lineno)
        a, b = r.number("first coordinate"), r.number("second coordinate")
        h = r.number("height")
        n, e = (a, b) if u.north_first else (b, a)
        scale = u.distance
        return (
            None if e is None else e * scale,
            None if n is None else n * scale,
            None if h is None else h * scale,
        )

    def station(self, line: str, lineno: int) -> None:
        r = self.rec(line, lineno)
        name = r.ident("station")
        e, n, h = self.plane(r)
        hi = r.number("instrument height")
        known = e is not None and n is not None
        self.setup = Setup(
            station=name,
            e=e or 0.0,
            n=n or 0.0,
            h=h or 0.0,
            instrument_height=(hi or 0.0) * self.need_units(lineno).distance,
            line=lineno,
            known=known,
            oriented=False,
        )
        self.out.setups.append(self.setup)

    def backsight(self, line: str, lineno: int) -> None:
        r = self.rec(line, lineno)
        u = self.need_units(lineno)
        r.ident("station")
        bs = r.ident("backsight point")
        az, circle = r.number("azimuth"), r.number("circle reading")
        if self.setup is None:
            raise InputError(
                "a backsight before any station record",
                path=self.path,
                line=lineno,
                field=f"{line[:4]}",
            )
        if az is None and bs in self.coords and self.setup.known:
            p = self.coords[bs]
            azimuth = math.atan2(p.e - self.setup.e, p.n - self.setup.n)
        else:
            azimuth = r.need(az, "azimuth") * u.angle
        reading = (circle or 0.0) * u.angle
        if not u.clockwise:
            reading = -reading
        new = replace(self.setup, orientation=azimuth - reading, oriented=True)
        self.setup = self.out.replace_setup(self.setup, new)

    def coordinate(self, line: str, lineno: int) -> None:
        r = self.rec(line, lineno)
        pid = r.ident("point")
        e, n, h = self.plane(r)
        if e is None or n is None:
            return  # a height-only or empty coordinate record places nothing in plan
        kp = KnownPoint(point=pid, e=e, n=n, h=h or 0.0, line=lineno)
        self.coords[pid] = kp
        self.out.known.append(kp)

    def observation(self, line: str, lineno: int) -> None:
        r = self.rec(line, lineno)
        u = self.need_units(lineno)
        stn = r.ident("station")
        tgt = r.ident("target")
        sd = r.number("slope distance")
        zen = r.need(r.number("zenith angle"), "zenith angle") * u.angle
        if self.elevation:  # the instrument record says vertical angles are elevations
            zen = math.pi / 2.0 - zen
        hz = r.need(r.number("horizontal angle"), "horizontal angle") * u.angle
        if not u.clockwise:
            hz = -hz
        if self.setup is None or stn != self.setup.station:
            earlier = [s for s in self.out.setups if s.station == stn]
            if earlier:  # back on a station set up before: its coordinates and orientation
                self.setup = earlier[-1]
            else:
                self.setup = Setup(station=stn, line=lineno, known=False)
                self.out.setups.append(self.setup)
        if sd is None:
            self.out.unreduced.setdefault(tgt, lineno)
            return
        if not 0.0 < zen < 2.0 * math.pi:
            raise InputError(
                "zenith angle out of range",
                path=self.path,
                line=lineno,
                field=f"{line[:4]} zenith angle",
            )
        self.out.observations.append(
            Observation(
                point=tgt,
                hz=hz,
                zenith=zen,
                slope_distance=sd * u.distance,
                horizontal_distance=None,
                reflector_height=self.target_h,
                setup=self.setup,
                line=lineno,
            )
        )

    def feed(self, line: str, lineno: int) -> None:
        kind = line[:2]
        if kind == "00":
            self.units = header_units(line, self.path, lineno)
            if line[4:9] != "SDR33" and line[4:7] == "SDR":
                self.id_w, self.num_w = 4, 10
        elif kind == "10" and len(line) > 20:
            self.id_w, self.num_w = (16, 16) if line[20] == "1" else (4, 10)
        elif kind == "01" and len(line) > 50:
            self.elevation = line[50] == "2"
        elif kind == "02":
            self.station(line, lineno)
        elif kind == "03":
            r = self.rec(line, lineno)
            self.target_h = r.need(r.number("target height"), "target height") * (
                self.need_units(lineno).distance
            )
        elif kind == "07":
            self.backsight(line, lineno)
        elif kind == "08":
            self.coordinate(line, lineno)
        elif kind == "09" and line[2:4] in ("F1", "F2"):
            self.observation(line, lineno)


def parse_sdr(text: str, path: str = "<sdr>") -> ObservationSet:
    """Read the records of an SDR33/SDR2x file; a damaged field names its line and field."""
    reader = _Reader(path)
    text = _CONTROL.sub("", text)  # STX/ETX framing of a serial download, a Ctrl-Z at the end
    for lineno, line in split_lines(text):
        reader.feed(line.rstrip("\n"), lineno)
    out = reader.out
    out.warn_unreduced("observation", "without a slope distance")
    out.format = "Sokkia SDR33" if reader.id_w == 16 else "Sokkia SDR2x"
    return out
