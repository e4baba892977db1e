"""Reader for Carlson RW5 raw files (SurvCE/SurvStar, also written by Leica and others).

Comma-separated records, each value prefixed by a two-letter tag:

- ``MO``: job options; ``UN`` distance unit (0 US feet, 1 metres, 2 international feet),
  ``AU`` angle unit (0 degrees, 1 gon).
- ``OC,OP<id>,N <n>,E <e>,EL <h>``: occupied point (a new setup with its coordinates).
- ``LS,HI<hi>,HR<hr>``: instrument and rod height (``HR`` alone: the rod height changed).
- ``BK,OP<stn>,BP<bs>,BS<azimuth>,BC<circle>``: backsight, orientation ω = BS − BC.
- ``SS``/``BD``/``FD``: ``OP<stn>,FP<target>,AR<angle right>,ZE<zenith>,SD<slope distance>``.
- ``SP,PN<id>,N <n>,E <e>,EL <h>``: a point stored by coordinates.
- ``--`` notes are passed over.

Degrees are packed ``DDD.MMSS`` as in the format's documentation (``AR90.3000`` is 90°30').
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
from station.survey.topcon import packed_dms

UNITS = {"0": 1200.0 / 3937.0, "1": 1.0, "2": FOOT_M}  # US survey foot, metre, foot


class _Reader:
    def __init__(self, path: str):
        self.path = path
        self.out = ObservationSet(format="Carlson RW5")
        self.metres = 1.0
        self.gon = False
        self.setup: Setup | None = None
        self.hr = 0.0

    def fields(self, vals: list[str]) -> dict[str, str]:
        out: dict[str, str] = {}
        for v in vals[1:]:
            v = v.strip()
            for tag in (
                "EL",
                "OP",
                "BP",
                "FP",
                "PN",
                "BS",
                "BC",
                "AR",
                "ZE",
                "SD",
                "HI",
                "HR",
                "UN",
                "AU",
                "N",
                "E",
                "AZ",
                "HD",
            ):
                if v.startswith(tag):
                    out.setdefault(tag, v[len(tag) :].strip())
                    break
        return out

    def num(self, f: dict[str, str], tag: str, key: str, lineno: int) -> float | None:
        raw = f.get(tag, "")
        if not raw:
            return None
        return read_number(raw, self.path, lineno, f"{key} {tag}")

    def angle(self, f: dict[str, str], tag: str, key: str, lineno: int) -> float | None:
        raw = f.get(tag, "")
        if not raw:
            return None
        try:
            return float(raw) * math.pi / 200.0 if self.gon else packed_dms(raw)
        except ValueError as exc:
            raise InputError(str(exc), path=self.path, line=lineno, field=f"{key} {tag}") from None

    def point(self, f: dict[str, str], key: str, lineno: int) -> tuple[float, float, float] | None:
        n, e = self.num(f, "N", key, lineno), self.num(f, "E", key, lineno)
        h = self.num(f, "EL", key, lineno) or 0.0
        if n is None or e is None:
            return None
        return e * self.metres, n * self.metres, h * self.metres

    def feed(self, line: str, lineno: int) -> None:
        vals = line.strip().split(",")
        key = vals[0].strip().upper()
        f = self.fields(vals)
        if key == "MO":
            self.metres = UNITS.get(f.get("UN", "1"), 1.0)
            self.gon = f.get("AU", "0") == "1"
        elif key == "OC":
            enh = self.point(f, key, lineno)
            e, n, h = enh or (0.0, 0.0, 0.0)
            self.setup = Setup(
                f.get("OP", ""), e, n, h, line=lineno, known=enh is not None, oriented=False
            )
            self.out.setups.append(self.setup)
        elif key == "SP":
            enh = self.point(f, key, lineno)
            if enh is not None:
                self.out.known.append(KnownPoint(f.get("PN", ""), *enh, line=lineno))
        elif key == "LS":
            hi, hr = self.num(f, "HI", key, lineno), self.num(f, "HR", key, lineno)
            if hi is not None and self.setup is not None:
                new = replace(self.setup, instrument_height=hi * self.metres)
                self.setup = self.out.replace_setup(self.setup, new)
            if hr is not None:
                self.hr = hr * self.metres
        elif key == "BK" and self.setup is not None:
            az = self.angle(f, "BS", key, lineno) or 0.0
            circle = self.angle(f, "BC", key, lineno) or 0.0
            new = replace(self.setup, orientation=az - circle, oriented=True)
            self.setup = self.out.replace_setup(self.setup, new)
        elif key in ("SS", "BD", "FD", "TR"):
            self.shot(f, key, lineno)

    def shot(self, f: dict[str, str], key: str, lineno: int) -> None:
        if self.setup is None:
            raise InputError("a shot before any OC record", path=self.path, line=lineno, field=key)
        target = f.get("FP", "")
        hz, zen = self.angle(f, "AR", key, lineno), self.angle(f, "ZE", key, lineno)
        sd = self.num(f, "SD", key, lineno)
        if hz is None or zen is None or sd is None:
            self.out.unreduced.setdefault(target, lineno)
            return
        self.out.observations.append(
            Observation(
                point=target,
                hz=hz,
                zenith=zen,
                slope_distance=sd * self.metres,
                horizontal_distance=None,
                reflector_height=self.hr,
                setup=self.setup,
                line=lineno,
            )
        )


def parse_rw5(text: str, path: str = "<rw5>") -> ObservationSet:
    """Read a Carlson RW5 file; a damaged value names its line and tag."""
    reader = _Reader(path)
    for lineno, line in split_lines(text):
        reader.feed(line, lineno)
    out = reader.out
    out.warn_unreduced("shot", "without angles and a slope distance")
    return out
