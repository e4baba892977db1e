"""The results CSV: one row per descent, a ``#`` header saying what it was computed from.

Read it back with ``pandas.read_csv(path, comment="#")``; text fields are quoted, so a ``#`` in
the notes stays part of them. Text fields are also safe to open in a
spreadsheet: a value beginning with ``=``, ``+``, ``-`` or ``@`` gets a leading apostrophe, so
it is shown as text, never run as a formula.
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
    "flags", "model", "mass_kg", "air_density", "skier", "ski", "wax", "notes",
]  # fmt: skip
TEXT_COLUMNS = [
    "missing",
    "status",
    "descent_status",
    "flags",
    "model",
    "skier",
    "ski",
    "wax",
    "notes",
]


def safe_text(value: Any) -> Any:
    """Neutralise spreadsheet formulas: ``=cmd|…`` becomes ``'=cmd|…``."""
    if isinstance(value, str) and value[:1] in ("=", "+", "-", "@"):
        return "'" + value
    return value


def results_frame(rows: list[dict[str, Any]]) -> pd.DataFrame:
    df = pd.DataFrame(rows, columns=COLUMNS)
    for col in TEXT_COLUMNS:
        df[col] = df[col].map(safe_text)
    return df


def write_results(rows: list[dict[str, Any]], path: str, header: dict[str, str]) -> None:
    """Write atomically (temp file + rename), so a reader never sees half a file."""
    df = results_frame(rows)
    lines = [f"# station {__version__} results"]
    lines += [f"# {k}: {str(v).replace(chr(10), ' ')}" for k, v in header.items()]
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".results-", suffix=".csv", dir=folder)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write("\n".join(lines) + "\n")
            df.to_csv(fh, index=False, float_format="%.10g", quoting=csv.QUOTE_NONNUMERIC)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def read_results(path: str) -> pd.DataFrame:
    return pd.read_csv(path, comment="#")
