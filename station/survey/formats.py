"""Which survey file is this? The format found from the file's content, and one way to read any.

Surveyors hand over what their instrument writes, under whatever name (an SDR33 job arrives as
``.sdr``, ``.tops`` or ``.txt``), so the extension decides nothing: the first records do. Every
reader has one interface, text and path → :class:`~station.survey.polar.ObservationSet` (setups,
polar observations, points given by coordinates), and each lives in its own module:

- Leica GSI-8/16: :mod:`station.survey.gsi` (+ :func:`station.survey.polar.interpret_gsi`)
- Sokkia SDR33/SDR2x: :mod:`station.survey.sdr`
- Topcon GTS-7 / TopSURV text: :mod:`station.survey.topcon`
- LandXML 1.2: :mod:`station.survey.landxml`
- Carlson RW5: :mod:`station.survey.rw5`

Files come over serial cables and from Windows tools: STX/ETX framing and other control
characters are dropped, and text that is not UTF-8 is read as Windows-1252 (then Latin-1), so
a degree sign or an umlaut in a comment never stops a read.
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Callable
from dataclasses import dataclass

from station.errors import InputError
from station.files import MAX_OBSERVATIONS, read_bytes
from station.survey.polar import ObservationSet, Setup

#: the observation formats, for the one line a file of none of them gets
OBSERVATION_FORMATS = (
    "Leica GSI-8/16, Sokkia SDR33/SDR2x, Topcon GTS-7/TopSURV, LandXML 1.2, Carlson RW5"
)
#: what ``station survey`` reads
FORMAT_NAMES = (
    f"a survey YAML (surveys/README.md), {OBSERVATION_FORMATS}, or a points CSV (id,e,n,h)"
)

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0c\x0e-\x1f\x7f]")


def decode(data: bytes) -> str:
    """Bytes of an instrument file as text: UTF-8 (BOM dropped), else Windows-1252, else
    Latin-1; serial framing (STX, ETX, EOT, Ctrl-Z …) removed, line ends kept."""
    data = data.removeprefix(b"\xef\xbb\xbf")  # a BOM (not the utf-8-sig codec: one import less)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        try:
            text = data.decode("cp1252")
        except UnicodeDecodeError:  # bytes Windows-1252 leaves undefined (0x81, 0x8d, …)
            text = data.decode("latin-1")
    return _CONTROL.sub("", text)


def _lines(text: str, n: int = 12) -> list[str]:
    out = []
    for line in text.replace("\r", "\n").split("\n"):
        if line.strip():
            out.append(line.strip())
            if len(out) >= n:
                break
    return out


_GSI_WORD = re.compile(r"^\*?\d\d[\d.]{4}[+-][0-9A-Za-z?.]{8,16}$")
_SDR_RECORD = re.compile(r"^\d\d[A-Z0-9]{2}")
_GTS_KEYS = {
    "GTS-700",
    "GTS-7",
    "JOB",
    "DATE",
    "NAME",
    "INST",
    "UNITS",
    "SCALE",
    "ATMOS",
    "TEMP",
    "STN",
    "XYZ",
    "BKB",
    "BS",
    "FS",
    "SS",
    "CTL",
    "HV",
    "SD",
    "HD",
    "OFFSET",
    "NOTE",
}
_RW5_RECORD = re.compile(r"^(--|(JB|MO|SP|OC|BK|LS|SS|BD|BR|FD|FR|TR|GPS|G[0-9]|PS|DP|CS),)")


def _is_gsi(lines: list[str]) -> bool:
    return bool(lines) and all(_GSI_WORD.match(w) for w in lines[0].split()[:3])


def _is_sdr(lines: list[str]) -> bool:
    return (
        bool(lines)
        and lines[0].startswith("00NM")
        and all(_SDR_RECORD.match(x) for x in lines[: min(4, len(lines))])
    )


def _gts_key(line: str) -> str:
    return re.split(r"[\s,]", line, maxsplit=1)[0].upper()


def _is_gts(lines: list[str]) -> bool:
    keyed = [x for x in lines if _gts_key(x) in _GTS_KEYS]
    has_obs = any(_gts_key(x) in {"STN", "UNITS", "SS", "SD"} for x in lines)
    return has_obs and len(keyed) >= max(2, len(lines) - 2)


def _is_landxml(lines: list[str]) -> bool:
    head = " ".join(lines[:3])
    return "<LandXML" in head or (head.startswith("<?xml") and "LandXML" in " ".join(lines))


def _is_rw5(lines: list[str]) -> bool:
    return len(lines) >= 2 and sum(bool(_RW5_RECORD.match(x)) for x in lines) >= len(lines) - 1


@dataclass(frozen=True)
class Format:
    """One observation-file format: its name, how to recognise it, and its reader, imported
    when a file of this format is read (a fit of a GSI survey loads no XML parser: see
    tests/test_startup.py)."""

    name: str
    sniff: Callable[[list[str]], bool]
    module: str
    function: str

    def read(self, text: str, path: str, default_setup: Setup | None = None) -> ObservationSet:
        """Read ``text`` (from ``path``); ``default_setup`` is the survey YAML's setup for
        GSI blocks before the first station block (the other formats name their setups)."""
        parse = getattr(importlib.import_module(self.module), self.function)
        if self.module == "station.survey.gsi":
            return parse(text, path, default_setup)
        return parse(text, path)


FORMATS = (
    Format("Leica GSI", _is_gsi, "station.survey.gsi", "read_gsi_text"),
    Format("Sokkia SDR", _is_sdr, "station.survey.sdr", "parse_sdr"),
    Format("LandXML", _is_landxml, "station.survey.landxml", "parse_landxml"),
    Format("Topcon GTS-7", _is_gts, "station.survey.topcon", "parse_gts7"),
    Format("Carlson RW5", _is_rw5, "station.survey.rw5", "parse_rw5"),
)


def is_points_csv(text: str) -> bool:
    """A coordinate list by its header: the columns id, e, n and h (any delimiter)."""
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    cells = {c.strip().lower() for c in re.split(r"[,;\t]", first.lstrip("\ufeff"))}
    return {"id", "e", "n", "h"} <= cells


def read_text(path: str) -> str:
    """An observation file's text (bounded size, any common encoding)."""
    return decode(read_bytes(path, MAX_OBSERVATIONS, "survey file"))


def sniff(text: str) -> Format | None:
    """The observation format of this text, or None (a YAML, a CSV, or unknown)."""
    lines = _lines(text)
    return next((f for f in FORMATS if f.sniff(lines)), None)


def read_observations(path: str, default_setup: Setup | None = None) -> ObservationSet:
    """Read any observation file the station knows; one line naming the formats otherwise."""
    text = read_text(path)
    fmt = sniff(text)
    if fmt is None:
        raise InputError(
            f"not a survey observation file: the station reads {FORMAT_NAMES}", path=path
        )
    return fmt.read(text, path, default_setup)
