"""One policy for every CSV file the station writes (results, crossing times, parsed events,
the comparison of items, survey tables, and later the season export).

A CSV is opened in a spreadsheet, and a cell is text the station did not choose: an item
name, a note, a line the timer sent. Two rules, applied here once for all writers:

- **formula-safe cells**: a text cell whose first character other than spaces, tabs and line
  breaks is ``=``, ``+``, ``-`` or ``@`` (or their full-width forms), or that begins with a
  tab or a line break, gets a leading apostrophe, so a spreadsheet shows it as text and never
  runs it as a formula (spreadsheets skip leading whitespace before a formula). A cell that is
  a plain decimal number (``-0.125``, ``1e-05``) is a number, not a formula, and is left as it
  is, so number columns written as text stay numbers.
- **header lines that cannot break**: a ``# key: value`` line has no control characters (CR,
  LF, TAB …: spaces), no commas and no semicolons (`` |``), so neither pandas'
  ``comment="#"`` nor a spreadsheet splitting on either makes a live row of a survey name or
  a note.

:func:`writer` is ``csv.writer`` with the first rule applied to every text cell.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterable
from typing import IO, Any

_FORMULA_START = frozenset("=+-@\uff1d\uff0b\uff0d\uff20")
_LEADING_BLANKS = " \t\r\n\f\v\u00a0\u3000"
_PLAIN_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


def safe_text(value: Any) -> Any:
    """A text field: ``=cmd|…`` (also `` \\t=cmd|…``, ``-2+3``) becomes ``'=cmd|…``; anything
    but text is returned as it is."""
    if not isinstance(value, str) or not value:
        return value
    first = value.lstrip(_LEADING_BLANKS)[:1]
    if first in _FORMULA_START or value[0] in "\t\r\n":
        return "'" + value
    return value


def safe_cell(value: Any) -> Any:
    """Any cell: a plain decimal number written as text stays as it is; other text is made
    formula-safe (:func:`safe_text`)."""
    if isinstance(value, str) and _PLAIN_NUMBER.fullmatch(value):
        return value
    return safe_text(value)


def header_text(value: Any) -> str:
    """A header value on one line without separators: control characters (CR, LF, TAB, …)
    become spaces, commas and semicolons become `` |``."""
    text = "".join(" " if (ord(c) < 32 or 0x7F <= ord(c) < 0xA0 or c in "\u2028\u2029") else c
                   for c in str(value))  # fmt: skip
    return " ".join(text.replace(",", " |").replace(";", " |").split())


def header_line(key: str, value: Any) -> str:
    """``# key: value`` on one line without commas or semicolons (:func:`header_text`)."""
    return f"# {header_text(key)}: {header_text(value)}"


class SafeWriter:
    """``csv.writer`` whose every text cell goes through :func:`safe_cell`."""

    def __init__(self, fh: IO[str], **kwargs: Any) -> None:
        kwargs.setdefault("lineterminator", "\n")
        self._w = csv.writer(fh, **kwargs)

    def writerow(self, row: Iterable[Any]) -> Any:
        return self._w.writerow([safe_cell(v) for v in row])

    def writerows(self, rows: Iterable[Iterable[Any]]) -> None:
        for row in rows:
            self.writerow(row)


def writer(fh: IO[str], **kwargs: Any) -> SafeWriter:
    """A CSV writer under the station's policy (lines end in LF unless told otherwise)."""
    return SafeWriter(fh, **kwargs)
