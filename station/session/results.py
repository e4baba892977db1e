"""The results CSV: one row per descent, a ``#`` header saying what it was computed from.

Read it back with ``pandas.read_csv(path, comment="#")``; text fields are quoted, so a ``#`` in
the notes stays part of them. Text fields are also safe to open in a spreadsheet: a value whose
first character other than spaces, tabs and line breaks is ``=``, ``+``, ``-`` or ``@`` (or
their full-width forms), or that begins with a tab or a line break, gets a leading apostrophe,
so it is shown as text, never run as a formula (spreadsheets skip leading whitespace before a
formula). Header values are put on one line with no commas or semicolons, so neither pandas
nor a spreadsheet splits a ``#`` line, whatever a survey name or a note contains.
"""

from __future__ import annotations

import csv
import os
import tempfile
from typing import Any

import pandas as pd

from station import __version__

COLUMNS = [
    "descent", "start_time", "photocells_used", "missing", "v0", "cda", "cda_lo", "cda_hi",
    "mu", "mu_lo", "mu_hi", "mu1", "sigma_s2", "rms_residual_ms", "status", "descent_status",
    "flags", "model", "mass_kg", "air_density", "wind_ms", "skier", "ski", "wax",
    "air_temperature_c",
    "snow_temperature_c", "pressure_hpa", "humidity_pct", "notes", "invalid_reason",
]  # fmt: skip
TEXT_COLUMNS = ["missing", "status", "descent_status", "flags", "model", "skier", "ski", "wax",
                "notes", "invalid_reason"]  # fmt: skip


_FORMULA_START = frozenset("=+-@\uff1d\uff0b\uff0d\uff20")
_LEADING_BLANKS = " \t\r\n\f\v\u00a0\u3000"


def safe_text(value: Any) -> Any:
    """Neutralise spreadsheet formulas: ``=cmd|…`` (also `` \t=cmd|…``) becomes ``'=cmd|…``."""
    if not isinstance(value, str) or not value:
        return value
    first = value.lstrip(_LEADING_BLANKS)[:1]
    if first in _FORMULA_START or value[0] in "\t\r\n":
        return "'" + value
    return value


def header_text(value: Any) -> str:
    """A header value on one line without separators: control characters (CR, LF, TAB, …)
    become spaces, commas and semicolons become `` |``."""
    text = "".join(" " if (ord(c) < 32 or 0x7F <= ord(c) < 0xA0 or c in "\u2028\u2029") else c
                   for c in str(value))  # fmt: skip
    return " ".join(text.replace(",", " |").replace(";", " |").split())


def results_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=COLUMNS)
    for col in TEXT_COLUMNS:
        df[col] = df[col].map(safe_text)
    # numbers as numbers (None -> empty), so they are written unquoted and read back as floats
    for col in COLUMNS:
        if col in TEXT_COLUMNS or col == "start_time":
            continue
        kind = "Int64" if col in ("descent", "photocells_used") else "float64"
        df[col] = pd.to_numeric(df[col]).astype(kind)
    return df


def _plain(value: Any) -> Any:
    """NaN/NA -> None (written empty); numpy scalars -> Python numbers (written unquoted)."""
    if value is None or value is pd.NA or (isinstance(value, float) and value != value):
        return None
    if hasattr(value, "item"):
        return value.item()
    return value


def write_results(rows: list[dict[str, Any]], path: str, header: dict[str, str]) -> None:
    """Write atomically (temp file + rename), so a reader never sees half a file."""
    df = results_frame(rows)
    lines = [f"# station {__version__} results"]
    lines += [f"# {header_text(k)}: {header_text(v)}" for k, v in header.items()]
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".results-", suffix=".csv", dir=folder)
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # as open() would make it; mkstemp makes it 0600
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write("\n".join(lines) + "\n")
            # the csv module, not DataFrame.to_csv: numbers must stay numbers (unquoted, full
            # precision) while every text field is quoted, so a "#" in the notes is safe
            w = csv.writer(fh, quoting=csv.QUOTE_NONNUMERIC, lineterminator="\n")
            w.writerow(list(df.columns))
            for row in df.itertuples(index=False):
                w.writerow([_plain(v) for v in row])
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _umask() -> int:
    """The process's umask, read without changing it (``os.umask`` would, for a moment, for
    every thread) where Linux tells it."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def read_results(path: str) -> pd.DataFrame:
    return pd.read_csv(path, comment="#")
