"""The results CSV: one row per descent, a ``#`` header saying what it was computed from and
the unit of each number column (``# units:``; the column names stay as they are, because other
code reads them).

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
    "flags", "model", "mass_kg", "air_density", "wind_ms", "skier", "ski", "wax",
    "air_temperature_c",
    "snow_temperature_c", "pressure_hpa", "humidity_pct", "notes", "invalid_reason",
]  # fmt: skip
TEXT_COLUMNS = ["missing", "status", "descent_status", "flags", "model", "skier", "ski", "wax",
                "notes", "invalid_reason"]  # fmt: skip


def safe_text(value: Any) -> Any:
    """Neutralise spreadsheet formulas: ``=cmd|…`` becomes ``'=cmd|…``."""
    if isinstance(value, str) and value[:1] in ("=", "+", "-", "@"):
        return "'" + value
    return value


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


#: the unit of each number column ("1" for a pure number), written in the ``# units:`` line
UNITS = {
    "descent": "1", "start_time": "ISO 8601 local time with UTC offset", "photocells_used": "1",
    "v0": "m/s", "cda": "m2", "cda_lo": "m2", "cda_hi": "m2", "mu": "1", "mu_lo": "1",
    "mu_hi": "1", "mu1": "s/m", "sigma_s2": "s2", "rms_residual_ms": "ms", "mass_kg": "kg",
    "air_density": "kg/m3", "wind_ms": "m/s (+ tailwind)", "air_temperature_c": "degC",
    "snow_temperature_c": "degC", "pressure_hpa": "hPa", "humidity_pct": "%",
}  # fmt: skip


def header_line(key: str, value: Any) -> str:
    """``# key: value`` on one line without commas (";" instead), so a spreadsheet that splits
    on commas keeps each header line in one cell, and pandas' ``comment="#"`` skips it."""
    text = " ".join(str(value).split()).replace(",", ";")
    return f"# {key}: {text}"


def write_results(rows: list[dict[str, Any]], path: str, header: dict[str, str]) -> None:
    """Write atomically (temp file + rename), so a reader never sees half a file."""
    df = results_frame(rows)
    lines = [f"# station {__version__} results"]
    lines += [header_line(k, v) for k, v in header.items()]
    lines.append(header_line("units", "; ".join(f"{k} {u}" for k, u in UNITS.items())))
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".results-", suffix=".csv", dir=folder)
    try:
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


def read_results(path: str) -> pd.DataFrame:
    return pd.read_csv(path, comment="#")
