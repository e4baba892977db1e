"""Reader for Topcon GTS-7 / TopSURV text exports: keyword records with comma-separated values.

Records used (GTS-700 raw format; other keywords such as JOB, INST, DATE, SCALE, NOTE are
passed over):

- ``UNITS M|F,D|G``: metres or feet; degrees or gon. Degrees are written packed as
  ``DDD.MMSSs`` (degrees, two digits of minutes, seconds with a tenth), as the format's
  documentation gives them: ``87.46350`` is 87°46'35.0".
- ``STN id,instrument height[,code]``: a new setup; ``XYZ e,n,h`` right after gives its
  coordinates (easting first).
- ``BKB id,azimuth,circle reading``: the backsight; the setup's orientation is azimuth − reading.
  An ``XYZ`` after it gives the backsight point's coordinates.
- ``BS id[,target height]``, ``FS``/``SS id,target height[,code]``: the target of the next
  observation record. ``HV hz,zenith`` (angles only) or ``SD hz,zenith,slope distance``;
  ``HD hz,horizontal distance,height difference`` is read as a horizontal distance.
"""

from __future__ import annotations

import math
from dataclasses import replace

from station.errors import InputError
from station.survey.gsi import FOOT_M, split_lines
from station.survey.polar import (
    KnownPoint,
    Observation,
    ObservationSet,
    Setup,
    read_number,
)


def packed_dms(text: str) -> float:
    """``DDD.MMSSs`` → radians; minutes and seconds must be below 60."""
    raw = text.strip()
    sign = -1.0 if raw.startswith("-") else 1.0
    raw = raw.lstrip("+-")
    whole, _, frac = raw.partition(".")
    if not whole.isdigit() or (frac and not frac.isdigit()):
        raise ValueError(f"{text!r} is not an angle DDD.MMSS")
    frac = (frac + "0000")[:4] + ("." + frac[4:] if len(frac) > 4 else "")
    minutes, seconds = int(frac[:2]), float(frac[2:])
    if minutes >= 60 or seconds >= 60:
        raise ValueError(f"{text!r} is not DDD.MMSS (minutes or seconds ≥ 60)")
    return sign * math.radians(int(whole) + minutes / 60.0 + seconds / 3600.0)


class _Reader:
    def __init__(self, path: str):
        self.path = path
        self.out = ObservationSet(format="Topcon GTS-7")
        self.metres = 1.0
        self.gon = False
        self.units_seen = False
        self.setup: Setup | None = None
        self.last = ""  # keyword of the last STN/BKB/BS/FS/SS record
        self.target = ""
        self.target_h = 0.0
        self.backsight = ""
        self.coords: dict[str, KnownPoint] = {}

    def number(self, vals: list[str], i: int, key: str, lineno: int, name: str) -> float | None:
        raw = vals[i].strip() if i < len(vals) else ""
        if not raw:
            return None
        return read_number(raw, self.path, lineno, f"{key} {name}")

    def angle(self, vals: list[str], i: int, key: str, lineno: int, name: str) -> float:
        raw = vals[i].strip() if i < len(vals) else ""
        if not raw:
            raise InputError("missing", path=self.path, line=lineno, field=f"{key} {name}")
        if not self.units_seen:
            raise InputError(
                "an angle before the UNITS record: unit unknown",
                path=self.path,
                line=lineno,
                field=f"{key} {name}",
            )
        try:
            if self.gon:
                return float(raw) * math.pi / 200.0
            return packed_dms(raw)
        except ValueError as exc:
            raise InputError(str(exc), path=self.path, line=lineno, field=f"{key} {name}") from None

    def units(self, vals: list[str], lineno: int) -> None:
        dist = vals[0].strip().upper() if vals else ""
        ang = vals[1].strip().upper() if len(vals) > 1 else ""
        if dist not in ("M", "F") or ang not in ("D", "G"):
            raise InputError(
                f"unknown units {','.join(vals)!r} (M or F, D or G)",
                path=self.path,
                line=lineno,
                field="UNITS",
            )
        self.metres = 1.0 if dist == "M" else FOOT_M
        self.gon = ang == "G"
        self.units_seen = True

    def xyz(self, vals: list[str], lineno: int) -> None:
        e, n, h = (self.number(vals, i, "XYZ", lineno, f) for i, f in enumerate("enh"))
        if e is None or n is None:
            return
        k = self.metres
        if self.last == "STN" and self.setup is not None:
            new = replace(self.setup, e=e * k, n=n * k, h=(h or 0.0) * k, known=True)
            self.setup = self.out.replace_setup(self.setup, new)
        elif self.last == "BKB" and self.backsight:
            self.coords[self.backsight] = KnownPoint(
                self.backsight, e * k, n * k, (h or 0.0) * k, lineno
            )
            self.out.known.append(self.coords[self.backsight])

    def observe(self, key: str, vals: list[str], lineno: int) -> None:
        if self.setup is None or self.last not in ("BS", "FS", "SS"):
            return  # the backsight's own angles (HV after BS) orient nothing beyond BKB
        if self.last == "BS":
            return
        hz = self.angle(vals, 0, key, lineno, "horizontal angle")
        if key == "HV":
            self.out.unreduced.setdefault(self.target, lineno)
            return
        if key == "SD":
            zen = self.angle(vals, 1, key, lineno, "zenith angle")
            sd = self.number(vals, 2, key, lineno, "slope distance")
            hd = None
        else:  # HD hz, horizontal distance, height difference: zenith from the two
            hd0 = self.number(vals, 1, key, lineno, "horizontal distance")
            dv = self.number(vals, 2, key, lineno, "height difference") or 0.0
            if hd0 is None:
                raise InputError(
                    "missing", path=self.path, line=lineno, field="HD horizontal distance"
                )
            zen = math.atan2(hd0, dv)
            sd, hd = None, hd0 * self.metres
        if key == "SD" and sd is None:
            self.out.unreduced.setdefault(self.target, lineno)
            return
        self.out.observations.append(
            Observation(
                point=self.target,
                hz=hz,
                zenith=zen,
                slope_distance=None if sd is None else sd * self.metres,
                horizontal_distance=hd,
                reflector_height=self.target_h,
                setup=self.setup,
                line=lineno,
            )
        )

    def feed(self, line: str, lineno: int) -> None:
        parts = line.strip().split(None, 1)  # the keyword, then blanks or a tab
        key = parts[0].upper() if parts else ""
        rest = parts[1] if len(parts) > 1 else ""
        vals = rest.strip().split(",") if rest.strip() else []
        if key == "UNITS":
            self.units(vals, lineno)
        elif key == "STN":
            hi = self.number(vals, 1, key, lineno, "instrument height") or 0.0
            self.setup = Setup(
                station=vals[0].strip() if vals else "",
                line=lineno,
                instrument_height=hi * self.metres,
                known=False,
                oriented=False,
            )
            self.out.setups.append(self.setup)
            self.last = key
        elif key == "XYZ":
            self.xyz(vals, lineno)
        elif key == "BKB":
            self.bkb(vals, lineno)
        elif key in ("BS", "FS", "SS"):
            self.target = vals[0].strip() if vals else ""
            self.target_h = (self.number(vals, 1, key, lineno, "target height") or 0.0) * (
                self.metres
            )
            self.last = key
        elif key in ("HV", "SD", "HD"):
            self.observe(key, vals, lineno)

    def bkb(self, vals: list[str], lineno: int) -> None:
        if self.setup is None:
            raise InputError(
                "a backsight before any STN record", path=self.path, line=lineno, field="BKB"
            )
        self.backsight = vals[0].strip() if vals else ""
        az = self.angle(vals, 1, "BKB", lineno, "azimuth")
        reading = self.angle(vals, 2, "BKB", lineno, "circle reading")
        new = replace(self.setup, orientation=az - reading, oriented=True)
        self.setup = self.out.replace_setup(self.setup, new)
        self.last = "BKB"


def parse_gts7(text: str, path: str = "<gts7>") -> ObservationSet:
    """Read a GTS-7 / TopSURV text export; a damaged value names its line and record."""
    reader = _Reader(path)
    for lineno, line in split_lines(text):
        reader.feed(line, lineno)
    out = reader.out
    out.warn_unreduced("shot", "with angles but no distance")
    return out
