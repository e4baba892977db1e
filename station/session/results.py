"""The results CSV: one row per descent, a ``#`` header saying what it was computed from and
the unit of each number column (``# units:``; the column names stay as they are, because other
code reads them).

Read it back with ``read_results`` or ``pandas.read_csv(path, comment="#")``; text fields are
quoted, so a ``#`` in the notes stays part of them. Text fields are also safe to open in a
spreadsheet, and header values cannot break their line, by the policy of every CSV the
station writes (:mod:`station.csvfiles`): a value whose first character other than blanks is
``=``, ``+``, ``-`` or ``@`` gets a leading apostrophe; header values have no line breaks,
commas or semicolons.
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import operator
import os
from collections.abc import Sequence
from typing import IO, Any

from station import __version__, csvfiles
from station.csvfiles import header_line, header_text, safe_text  # noqa: F401 - one policy
from station.errors import InputError
from station.files import decode_text, read_bytes, replaced

COLUMNS = [
    "descent", "start_time", "photocells_used", "missing", "v0", "cda", "cda_lo", "cda_hi",
    "mu", "mu_lo", "mu_hi", "mu1", "sigma_s2", "rms_residual_ms", "status", "descent_status",
    "flags", "model", "mass_kg", "air_density", "gravity", "wind_ms", "skier", "ski", "wax",
    "air_temperature_c",
    "snow_temperature_c", "pressure_hpa", "humidity_pct", "notes", "invalid_reason",
]  # fmt: skip
TEXT_COLUMNS = ["missing", "status", "descent_status", "flags", "model", "skier", "ski", "wax",
                "notes", "invalid_reason"]  # fmt: skip


INT_COLUMNS = ("descent", "photocells_used")
#: the columns written as text (quoted)
_TEXT = frozenset([*TEXT_COLUMNS, "start_time"])


def _number(value: Any, col: str) -> int | float | None:
    """A number cell as a plain Python number (written unquoted, full precision); None or NaN
    -> None (written empty). The csv module, not pandas: a command that writes results should
    not pay pandas' import time."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return None
    if col not in INT_COLUMNS:
        number = float(value)  # numpy scalars and numeric strings too; text raises ValueError
        return None if math.isnan(number) else number
    try:
        return operator.index(value)
    except TypeError:
        number = float(value)
        if not number.is_integer():
            raise ValueError(f"{col} {value!r} is not a whole number") from None
        return int(number)


def results_frame(rows: list[dict[str, Any]]) -> list[list[Any]]:
    """The cells of each row in ``COLUMNS`` order: text made spreadsheet-safe, numbers as
    numbers (so they are written unquoted and read back as floats), missing as None."""
    return [[cell_value(col, row.get(col)) for col in COLUMNS] for row in rows]


#: the unit of each number column ("1" for a pure number), written in the ``# units:`` line
UNITS = {
    "descent": "1", "start_time": "ISO 8601 local time with UTC offset", "photocells_used": "1",
    "v0": "m/s", "cda": "m2", "cda_lo": "m2", "cda_hi": "m2", "mu": "1", "mu_lo": "1",
    "mu_hi": "1", "mu1": "s/m", "sigma_s2": "s2", "rms_residual_ms": "ms", "mass_kg": "kg",
    "air_density": "kg/m3", "gravity": "m/s2", "wind_ms": "m/s (+ tailwind)",
    "air_temperature_c": "degC",
    "snow_temperature_c": "degC", "pressure_hpa": "hPa", "humidity_pct": "%",
}  # fmt: skip


def write_results_to(fh: IO[str], rows: list[dict[str, Any]], header: dict[str, str]) -> None:
    """The results CSV into an open text file (``newline=""``), e.g. standard output."""
    head, lines = results_lines(rows, header)
    fh.write(head)
    fh.write("".join(lines))


class RowWriter:
    """The text of one row of cells (:func:`results_frame`) as the results CSV writes it.

    The csv module, not DataFrame.to_csv: numbers must stay numbers (unquoted, full
    precision) while every text field is quoted, so a "#" in the notes is safe."""

    def __init__(self) -> None:
        self._buf = io.StringIO()
        self._w = csvfiles.writer(self._buf, quoting=csv.QUOTE_NONNUMERIC)

    def text(self, cells: Sequence[Any]) -> str:
        self._buf.seek(0)
        self._buf.truncate()
        self._w.writerow(cells)
        return self._buf.getvalue()


def results_lines(rows: list[dict[str, Any]], header: dict[str, str]) -> tuple[str, list[str]]:
    """The results CSV as its head (``#`` lines and column names) and the text of each row
    (a row is one line unless its notes hold a line break): what :func:`write_results_to`
    writes, in pieces, so ``station annotate`` knows where each row is and can change one
    row without reading the others (:mod:`station.session.resultsstate`)."""
    lines = [f"# station {__version__} results"]
    lines += [header_line(k, v) for k, v in header.items()]
    lines.append(header_line("units", " | ".join(f"{k} {u}" for k, u in UNITS.items())))
    w = RowWriter()
    head = "\n".join(lines) + "\n" + w.text(COLUMNS)
    return head, [w.text(cells) for cells in results_frame(rows)]


def parse_row(text: str) -> list[Any]:
    """The cells of one row's text as :func:`results_frame` made them (text as str, numbers
    as int or float, an empty number None), for :class:`RowWriter` to write again: the bytes
    are the same (floats are written as ``repr``, which reads back to the same float). A row
    that is not one of ``COLUMNS`` is ``ValueError``."""
    try:
        cells = next(csv.reader(io.StringIO(text, newline="")))
    except (StopIteration, csv.Error) as exc:
        raise ValueError(f"not a results row: {exc}") from None
    if len(cells) != len(COLUMNS):
        raise ValueError(f"{len(cells)} cells, not {len(COLUMNS)}")
    out: list[Any] = []
    for col, cell in zip(COLUMNS, cells, strict=True):
        if col in _TEXT:
            out.append(cell)
        elif cell == "":
            out.append(None)
        else:
            out.append(int(cell) if col in INT_COLUMNS else float(cell))
    return out


def cell_value(col: str, value: Any) -> Any:
    """One cell as :func:`results_frame` makes it."""
    if col in _TEXT:
        missing = isinstance(value, float) and math.isnan(value)
        return None if missing else safe_text(value)
    return _number(value, col)


def append_results(
    path: str, rows: list[dict[str, Any]], size: int, inode: int | None = None
) -> int:
    """Append rows to a results CSV that is ``size`` bytes long, as :func:`write_results_to`
    would have written them after the rows before: a recording adds each descent's row
    without rewriting the day's (the per-descent cost stays flat over a 2000-descent day).

    Returns the new size. The file must still be ``size`` bytes and the file ``inode`` (no one
    else wrote or replaced it since): otherwise ``ValueError``, and the caller rewrites it. A
    write that fails (disk full) is undone (the file cut back to ``size``) and raised: no
    reader sees half a row."""
    buf = io.StringIO()
    w = csvfiles.writer(buf, quoting=csv.QUOTE_NONNUMERIC)
    w.writerows(results_frame(rows))
    data = buf.getvalue().encode("utf-8")
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        st = os.fstat(fd)
        if st.st_size != size or (inode is not None and st.st_ino != inode):
            raise ValueError(f"{path} changed since it was written")
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
        except BaseException:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, size)
            raise
    finally:
        os.close(fd)
    return size + len(data)


def write_results(rows: list[dict[str, Any]], path: str, header: dict[str, str]) -> None:
    """Write atomically (:func:`station.files.replaced`), so a reader never sees half a
    file."""
    with replaced(path) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        write_results_to(fh, rows, header)


#: a day's results CSV: a few hundred bytes a descent
MAX_RESULTS = 64 * 1024 * 1024


def read_results(path: str) -> list[dict[str, Any]]:
    """The rows as written: numbers as int (descent, photocells_used) or float, text as str,
    empty cells as None. Only the ``#`` lines above the column names are skipped: a line of
    quoted notes may begin with ``#`` too.

    The one reader of a results CSV (``station sessions``, ``annotate``'s check of the
    descents, the tests). Only a regular file is opened, and at most :data:`MAX_RESULTS` bytes
    of it are read, so a FIFO or a link to ``/dev/zero`` is one line, not a hang; a file that
    is not a results CSV (binary, damaged, a number column with text) is one
    :class:`InputError` naming the file, its line and the column."""
    what = "results CSV"
    text = decode_text(read_bytes(path, MAX_RESULTS, what), path, what)
    lines = io.StringIO(text, newline="").readlines()  # line ends as the csv module wants
    start = next((i for i, line in enumerate(lines) if not line.startswith("#")), len(lines))
    reader = csv.reader(lines[start:])
    try:
        names = next(reader, [])
        if names and "descent" not in names:
            raise InputError(f"not a {what}: no descent column", path=path, line=start + 1)
        rows = []
        for cells in reader:
            row: dict[str, Any] = {}
            for col, cell in zip(names, cells, strict=False):
                row[col] = _cell(cell, col, path, start + reader.line_num)
            rows.append(row)
    except csv.Error as exc:
        raise InputError(f"not a {what}: {exc}", path=path, line=start + reader.line_num) from None
    return rows


def _cell(cell: str, col: str, path: str, line: int) -> Any:
    if cell == "":
        return None
    if col in TEXT_COLUMNS or col == "start_time" or col not in COLUMNS:
        return cell
    try:
        return int(cell) if col in INT_COLUMNS else float(cell)
    except ValueError:
        kind = "a whole number" if col in INT_COLUMNS else "a number"
        raise InputError(f"{cell[:20]!r} is not {kind}", path=path, line=line, field=col) from None
