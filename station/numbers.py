"""Numbers as people type them: a decimal point or a decimal comma, never NaN or infinity.

A test engineer on a German, French or Italian laptop types ``72,5`` and a European spreadsheet
saves ``10:41:07,2345``. Read with ``float`` the first is an error and, split at the comma, the
second silently becomes whole seconds. Here both are read as decimal marks. A number with both
a point and a comma (``1,234.5``) is refused: whether the comma groups thousands cannot be known.
Only ASCII digits count (``float`` would also take other scripts' digits, such as ``٣``).
"""

from __future__ import annotations

import math
import re

_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:[.,][0-9]*)?|[.,][0-9]+)(?:[eE][+-]?[0-9]+)?")


def parse_number(text: str) -> float:
    """A finite float from ``text`` with a decimal point or comma; ValueError with a plain
    reason otherwise."""
    s = text.strip()
    if not _NUMBER.fullmatch(s):
        if "," in s and "." in s:
            raise ValueError(f"{text!r} has both a decimal point and a comma")
        raise ValueError(f"{text!r} is not a number")
    value = float(s.replace(",", "."))
    if not math.isfinite(value):
        raise ValueError(f"{text!r} is too large")
    return value
