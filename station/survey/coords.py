"""Surveyed points given as coordinates: a CSV with columns ``id,e,n,h`` and optionally
``sigma_h`` (and ``sigma_xy``), metres, grid coordinates.

Many runs are surveyed with a GNSS rover, or exported from the total station's software as
coordinates rather than raw observations. European spreadsheets write ``;`` between fields and a
decimal comma (``1650,123``); both forms read. Every number must be finite and in range; a bad
one is reported with file, line and column, never guessed.
"""

from __future__ import annotations

import csv
import io
import math
import os

from station.errors import InputError
from station.survey.polar import ReducedPoint

REQUIRED = ("id", "e", "n", "h")
OPTIONAL = ("sigma_h", "sigma_xy")
#: grid coordinates beyond this (m) are no projection in use (UTM northings stay below 1e7)
MAX_COORD_M = 1e8
MIN_H_M, MAX_H_M = -500.0, 9000.0
#: a height precision beyond this (m) is no survey of a profile
MAX_SIGMA_M = 1.0


def _number(text: str, decimal_comma: bool, path: str, line: int, column: str) -> float:
    raw = text.strip()
    value_text = raw.replace(",", ".") if decimal_comma else raw
    try:
        value = float(value_text)
    except ValueError:
        hint = (
            " (a decimal comma needs ';' between the fields)"
            if "," in raw and not decimal_comma
            else ""
        )
        raise InputError(
            f"{raw!r} is not a number{hint}", path=path, line=line, field=column
        ) from None
    if not math.isfinite(value):
        raise InputError(f"{raw!r} is not a finite number", path=path, line=line, field=column)
    return value


def read_points_csv(path: str, default_sigma_h: float) -> list[ReducedPoint]:
    """Read a coordinate list; ``default_sigma_h`` (m) where no ``sigma_h`` column is given."""
    text = _read_text(path)
    lines = text.splitlines()
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise InputError("empty coordinate file (expected a header id,e,n,h)", path=path)
    header_line = lines[first]
    delimiter = ";" if ";" in header_line else ("\t" if "\t" in header_line else ",")
    decimal_comma = delimiter != ","
    reader = csv.reader(io.StringIO(text), delimiter=delimiter)
    rows = list(reader)
    header = [h.strip().lower() for h in rows[first]]
    _check_header(header, path, first + 1)
    col = {c: header.index(c) for c in header}
    points: list[ReducedPoint] = []
    seen: dict[str, int] = {}
    for i, row in enumerate(rows[first + 1 :], start=first + 2):
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise InputError(
                f"{len(row)} fields where the header has {len(header)}",
                path=path,
                line=i,
            )
        pid = row[col["id"]].strip()
        if not pid:
            raise InputError("empty point id", path=path, line=i, field="id")
        if pid in seen:
            raise InputError(
                f"point id {pid!r} already given on line {seen[pid]}",
                path=path,
                line=i,
                field="id",
            )
        seen[pid] = i
        points.append(_point(pid, row, col, decimal_comma, default_sigma_h, path, i))
    if not points:
        raise InputError("no points below the header", path=path, line=first + 1)
    return points


def _read_text(path: str) -> str:
    """The coordinate file's text, or an InputError that says why it cannot be read."""
    if os.path.isdir(path):
        raise InputError("is a folder, not a coordinate file", path=path)
    if os.path.exists(path) and not os.path.isfile(path):
        raise InputError("not a regular file (a device or pipe?)", path=path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            return fh.read()
    except IsADirectoryError:
        raise InputError("is a folder, not a coordinate file", path=path) from None
    except OSError as exc:
        raise InputError(f"cannot read coordinate file: {exc.strerror}", path=path) from None
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 text file", path=path) from None


def _check_header(header: list[str], path: str, line: int) -> None:
    """The header names the required columns and no others."""
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)}; the header must name id,e,n,h "
            f"(optional sigma_h, sigma_xy), found {','.join(header)!r}",
            path=path,
            line=line,
        )
    unknown = [c for c in header if c not in REQUIRED + OPTIONAL]
    if unknown:
        raise InputError(
            f"unknown column(s) {', '.join(unknown)} (id, e, n, h, sigma_h, sigma_xy)",
            path=path,
            line=line,
        )


def _point(
    pid: str,
    row: list[str],
    col: dict[str, int],
    decimal_comma: bool,
    default_sigma_h: float,
    path: str,
    i: int,
) -> ReducedPoint:
    """One row's point, its numbers checked (line ``i`` of the file)."""
    vals = {
        c: _number(row[col[c]], decimal_comma, path, i, c)
        for c in ("e", "n", "h", *OPTIONAL)
        if c in col and (c in REQUIRED or row[col[c]].strip())
    }
    for c in ("e", "n"):
        if abs(vals[c]) > MAX_COORD_M:
            raise InputError(f"{vals[c]!r} m is not a grid coordinate", path=path, line=i, field=c)
    if not MIN_H_M <= vals["h"] <= MAX_H_M:
        raise InputError(
            f"height {vals['h']!r} m is not on the earth's surface ({MIN_H_M:g} .. {MAX_H_M:g} m)",
            path=path,
            line=i,
            field="h",
        )
    for c in OPTIONAL:
        if c in vals and not 0.0 < vals[c] <= MAX_SIGMA_M:
            raise InputError(
                f"a standard deviation in metres must lie in (0, {MAX_SIGMA_M:g}], got {vals[c]!r}",
                path=path,
                line=i,
                field=c,
            )
    sigma_h = vals.get("sigma_h", default_sigma_h)
    return ReducedPoint(
        point=pid,
        e=vals["e"],
        n=vals["n"],
        h=vals["h"],
        sigma_h=sigma_h,
        sigma_xy=vals.get("sigma_xy", sigma_h),
        horizontal_distance=math.inf,  # no instrument distance: never "unobserved"
        setup="coordinates",
        line=i,
    )
