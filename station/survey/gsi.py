"""Reader for Leica GSI-8 and GSI-16 files: lines of words -> blocks of decoded values.

A GSI file is one block per line (CR, LF or CRLF; bare CR in old files). A block is words
separated by blanks. Each word is ``WI(2) info(3) unit(1) sign(1) data(8|16)``; GSI-16 blocks
start with ``*`` and carry 16-digit data. The unit digit (6th character) says how to read the
data: see :data:`UNITS`. This module only decodes words; what a block *means* (station setup,
measurement, known point) is decided in :mod:`station.survey.polar`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from station.errors import InputError
from station.survey.polar import ObservationSet, Setup, interpret_gsi

#: the international foot (every reader of a file in feet uses this one)
FOOT_M = 0.3048

#: unit digit -> (kind, divisor, factor to SI). Angles go to radians, lengths to metres.
UNITS: dict[str, tuple[str, float, float]] = {
    "0": ("length", 1e3, 1.0),
    "1": ("length", 1e3, FOOT_M),
    "2": ("angle", 1e5, math.pi / 200.0),  # gon
    "3": ("angle", 1e5, math.pi / 180.0),  # decimal degrees
    "4": ("angle", 1e5, math.nan),  # DDD.MMSSs, decoded digit-wise
    "5": ("angle", 1e4, 2.0 * math.pi / 6400.0),  # mil
    "6": ("length", 1e4, 1.0),
    "7": ("length", 1e4, FOOT_M),
    "8": ("length", 1e5, 1.0),
}

#: word indices holding an angle and those holding a length; others are kept as text.
ANGLE_WI = {"21", "22", "25"}
LENGTH_WI = {"31", "32", "33", "81", "82", "83", "84", "85", "86", "87", "88"}

WORD_NAMES = {
    "11": "point id",
    "21": "Hz",
    "22": "zenith angle",
    "25": "orientation Hz0-Hz",
    "31": "slope distance",
    "32": "horizontal distance",
    "33": "height difference",
    "81": "target E",
    "82": "target N",
    "83": "target H",
    "84": "station E",
    "85": "station N",
    "86": "station H",
    "87": "reflector height",
    "88": "instrument height",
}


@dataclass(frozen=True)
class GsiWord:
    """One decoded word: ``value`` in radians or metres for angle/length words, else None."""

    wi: str
    info: str
    unit: str
    text: str
    value: float | None


@dataclass
class GsiBlock:
    """One line of a GSI file: its words by word index, and where it stood."""

    line: int
    words: dict[str, GsiWord] = field(default_factory=dict)
    gsi16: bool = False

    def has(self, *wis: str) -> bool:
        return all(w in self.words for w in wis)

    def value(self, wi: str) -> float | None:
        word = self.words.get(wi)
        return None if word is None else word.value

    @property
    def point_id(self) -> str | None:
        word = self.words.get("11")
        if word is None:
            return None
        pid = word.text.lstrip("0")
        return pid if pid else "0"


def _dms_to_rad(digits: str) -> float:
    """DDD.MMSSs packed as an integer with 5 decimals: 3545100 -> 35°45'10.0"."""
    v = int(digits)
    deg, rest = divmod(v, 100000)
    minutes, tenths = divmod(rest, 1000)
    if minutes >= 60 or tenths >= 600:
        raise ValueError(f"{digits} is not DDD.MMSSs (minutes or seconds >= 60)")
    return math.radians(deg + minutes / 60.0 + tenths / 36000.0)


def decode_word(token: str) -> GsiWord:
    """Decode one word; raises ValueError with a plain reason when it is malformed."""
    if len(token) not in (15, 23):
        raise ValueError(
            f"word {token!r} has {len(token)} characters, expected 15 (GSI-8) or 23 (GSI-16)"
        )
    wi = token[0:2]
    info = token[2:6]
    unit = token[5]
    sign = token[6]
    data = token[7:]
    if not wi.isdigit():
        raise ValueError(f"word {token!r} does not start with a two-digit word index")
    if sign not in "+-":
        raise ValueError(f"word {token!r} has {sign!r} where the sign + or - belongs")
    value: float | None = None
    if wi in ANGLE_WI or wi in LENGTH_WI:
        want = "angle" if wi in ANGLE_WI else "length"
        if unit not in UNITS:
            raise ValueError(f"word {token!r}: unknown unit digit {unit!r}")
        kind, divisor, factor = UNITS[unit]
        if kind != want:
            raise ValueError(
                f"word {token!r}: unit digit {unit!r} is a {kind} unit, WI {wi} needs a {want}"
            )
        if not data.isdigit():
            raise ValueError(f"word {token!r}: data {data!r} is not a number")
        value = _dms_to_rad(data) if unit == "4" else int(data) / divisor * factor
        if sign == "-":
            value = -value
    return GsiWord(wi=wi, info=info, unit=unit, text=data, value=value)


def split_lines(text: str) -> list[tuple[int, str]]:
    """Lines with 1-based numbers, accepting CR, LF and CRLF; blank lines are dropped.

    Line numbers count physical line ends the way an editor shows them, so an error message
    points where the user looks. A bare-CR file counts each CR as a line end.
    """
    normalised = text.replace("\r\n", "\n").replace("\r", "\n")
    return [(i, s) for i, s in enumerate(normalised.split("\n"), start=1) if s.strip()]


def parse_gsi(text: str, path: str = "<gsi>") -> list[GsiBlock]:
    """Decode every block of a GSI file; a malformed word raises InputError with its line."""
    blocks: list[GsiBlock] = []
    for lineno, line in split_lines(text):
        tokens = line.split()
        gsi16 = tokens[0].startswith("*")
        block = GsiBlock(line=lineno, gsi16=gsi16)
        for n, token in enumerate(tokens):
            raw = token[1:] if n == 0 and gsi16 else token
            try:
                word = decode_word(raw)
            except ValueError as exc:
                wi = raw[:2] if raw[:2].isdigit() else f"word {n + 1}"
                name = WORD_NAMES.get(wi)
                label = f"WI {wi} ({name})" if name else (f"WI {wi}" if wi.isdigit() else wi)
                raise InputError(str(exc), path=path, line=lineno, field=label) from None
            if gsi16 and len(raw) != 23 or not gsi16 and len(raw) != 15:
                fmt = "GSI-16 (block starts with *)" if gsi16 else "GSI-8"
                raise InputError(
                    f"word {raw!r} does not fit a {fmt} block",
                    path=path,
                    line=lineno,
                    field=f"WI {word.wi}",
                )
            block.words[word.wi] = word
        blocks.append(block)
    return blocks


def read_gsi_text(
    text: str, path: str = "<gsi>", default_setup: Setup | None = None
) -> ObservationSet:
    """A GSI file's text → setups, observations and known points (see ``interpret_gsi``)."""
    return interpret_gsi(parse_gsi(text, path), path, default_setup)


def read_gsi(path: str) -> list[GsiBlock]:
    """Read and decode a GSI file from disk."""
    from station.files import MAX_OBSERVATIONS, read_bytes

    text = read_bytes(path, MAX_OBSERVATIONS, "GSI file").decode("latin-1")
    return parse_gsi(text, path)
