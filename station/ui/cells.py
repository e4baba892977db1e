"""The results table's columns and cells, and the panel's number formats: what the UI shows
of a descent's row, at the terminal's width."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from station.model.estimate import Estimate
from station.report.text import local_time
from station.session.analysis import DescentResult
from station.session.records import FitModel, ResultRow


@dataclass(frozen=True)
class Column:
    """A column of the descents table: its heading, key, width in cells, and whether its
    values are numbers (right-aligned)."""

    label: str
    key: str
    width: int
    number: bool = False


#: below this width the table takes its narrow set of columns
NARROW_TABLE = 130


#: the vertical scrollbar of the table, kept free so the last column is never under it
SCROLLBAR = 2


def table_columns(width: int) -> list[Column]:
    """The columns for a terminal ``width`` cells wide. Every number column is wide enough for
    its values (a number is never cut: ``fixed_width`` drops decimals first, then says ``#``); what
    does not fit at 80 columns is abbreviated (status, start without seconds) or left to the
    result panel, which shows the selected descent in full. Notes take what is left."""
    if width < NARROW_TABLE:
        cols = [
            Column("#", "n", 3, True), Column("start", "start", 5), Column("ski", "ski", 12),
            Column("wax", "wax", 8), Column("μ", "mu", 7, True), Column("±90%", "mu_pm", 7, True),
            Column("CdA", "cda", 6, True), Column("v0", "v0", 5, True),
            Column("rms", "rms", 4, True), Column("st", "status", 6),
        ]  # fmt: skip
        used = sum(c.width + 1 for c in cols) + SCROLLBAR + 1
        if width - used < 12:  # the interval is in the result panel: notes keep some room
            cols = [c for c in cols if c.key != "mu_pm"]
            used = sum(c.width + 1 for c in cols) + SCROLLBAR + 1
        return [*cols, Column("notes", "notes", max(8, width - used))]
    cols = [
        Column("#", "n", 3, True), Column("start", "start", 8), Column("ski", "ski", 12),
        Column("wax", "wax", 12), Column("μ", "mu", 7, True),
        Column("μ 90 %", "mu_ci", 15, True), Column("CdA", "cda", 6, True),
        Column("v0", "v0", 5, True), Column("rms ms", "rms", 6, True),
        Column("status", "status", 20),
    ]  # fmt: skip
    rest = max(16, width - sum(c.width + 1 for c in cols) - SCROLLBAR - 2)
    return [*cols, Column("flags", "flags", rest // 2), Column("notes", "notes", rest - rest // 2)]


#: statuses in the narrow table (the help explains them; the result panel says them in full)
SHORT_STATUS = {
    "ok": "ok", "ill-conditioned": "ill", "lift-off": "lift", "stopped": "stop",
    "too-few-photocells": "few", "not-converged": "nc", "poor-fit": "poor", "aborted": "abort",
    "error": "ERR", "invalid": "INV",
}  # fmt: skip


def fixed_width(v: float | None, decimals: int, width: int) -> str:
    """A number in at most ``width`` characters, never cut: fewer decimals first, then the
    exponent form, and a column of ``#`` (as spreadsheets do) if even that does not fit."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    for d in range(decimals, -1, -1):
        text = f"{v:.{d}f}"
        if len(text) <= width:
            return text
    text = f"{v:.0e}"
    return text if len(text) <= width else "#" * width


def middle(text: str, width: int) -> str:
    """Text in ``width`` cells, cut in the middle where it must be ("demo…ir A")."""
    if len(text) <= width:
        return text
    tail = (width - 1) // 2
    return text[: width - 1 - tail] + "…" + text[len(text) - tail :]


def fmt(v: Any, spec: str) -> str:
    return "—" if v is None or (isinstance(v, float) and v != v) else format(v, spec)


def cell(res: DescentResult, col: Column) -> str:
    """The text of one cell of the table for a descent."""
    row, w = res.row, col.width
    key = col.key
    if key == "n":
        return str(res.number)
    if key == "start":
        clock = res.start_time[11:19] if "T" in res.start_time else res.start_time[:8]
        return clock[:w]
    if key in ("ski", "wax"):  # an item's name often differs at its end: "pair A", "pair B"
        return middle(getattr(row, key), w)
    if key == "notes":
        return row.notes
    if key == "mu":
        return fixed_width(row.mu, 5, w)
    if key == "mu_ci":
        if row.mu_lo is None or row.mu_hi is None:
            return "—"
        return f"{fixed_width(row.mu_lo, 5, 7)}–{fixed_width(row.mu_hi, 5, 7)}"
    if key == "mu_pm":
        if row.mu_lo is None or row.mu_hi is None:
            return "—"
        return fixed_width((row.mu_hi - row.mu_lo) / 2, 5, w)
    if key == "cda":
        return fixed_width(row.cda, 4, w)
    if key == "v0":
        return fixed_width(row.v0, 2, w)
    if key == "rms":
        return fixed_width(row.rms_residual_ms, 2, w)
    if key == "status":
        return _status_cell(row, w)
    if key == "flags":
        invalid = [f"invalid: {row.invalid_reason}"] if row.invalid else []
        return "; ".join([*invalid, *row.flags])
    raise KeyError(key)


def _status_cell(row: ResultRow, w: int) -> str:
    velocity = row.model == FitModel.VELOCITY
    if w < 10:  # narrow: short status, v for the velocity model, ! when there are flags
        short = "INV" if row.invalid else SHORT_STATUS.get(row.status.value, "?")
        marks = ("v" if velocity else "") + ("!" if row.flags else "")
        return f"{short} {marks}".strip()
    status = "INVALID" if row.invalid else row.status.value
    return status + (" (v)" if velocity else "")


def conditions(row: ResultRow) -> str:
    """What the fit took as known: a wrong mass (72,5 read as 725) shows here at once."""
    wind = f" · wind {row.wind_ms:g} m/s" if row.wind_ms else ""
    air = f"air {row.air_density:.3f} kg/m³"
    return f"mass {row.mass_kg:g} kg · {air} · g {row.gravity:.5f} m/s²{wind}"


def justify(text: str, col: Column) -> str:
    """One space before every column, numbers right-aligned (the table has no padding of its
    own: at 80 columns every cell counts)."""
    return " " + (text.rjust(col.width) if col.number else text)


def _estimate_line(label: str, est: Estimate, spec: str, unit: str) -> str:
    c = est.ci90
    if c:
        rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]"
    elif est.not_identifiable:
        rng = "not identifiable"
    else:
        rng = "no interval"
    return f"{label:<4}{fmt(est.value, spec):>9} {unit:<4} {rng}"


def panel_text(res: DescentResult) -> str:
    """The result panel of one descent: its fit with intervals, its status and flags, the
    conditions it was fitted with; or why there is no fit."""
    f, row, d = res.fit, res.row, res.descent
    head = f"descent {d.number} · {local_time(res.start_time)} · "
    if f is None:
        status = f"INVALID: {row.invalid_reason} ({row.status})" if row.invalid else row.status
        return head + f"{status}: {'; '.join(row.flags)}\n" + conditions(row)
    status = row.status.value
    if row.invalid:
        status = f"INVALID: {row.invalid_reason} (fit {status})"
    notes = "; ".join(x for x in (*row.flags, f.message, row.notes) if x)
    mu1 = ""
    if f.mu1 is not None:  # the velocity model's μ1: always with its interval, flagged when ∋ 0
        mu1 = "\n" + _estimate_line("μ1", f.mu1, ".2e", "s/m")
        mu1 += "  (not distinguishable from 0)" if f.mu1.consistent_with_zero else ""
    return (
        head
        + f"{len(d.photocells)} photocells · {status}\n"
        + _estimate_line("μ", f.mu, ".5f", "")
        + "   "
        + _estimate_line("CdA", f.cda, ".4f", "m²")
        + "\n"
        + _estimate_line("v0", f.v0, ".3f", "m/s")
        + f"   rms {fmt(row.rms_residual_ms, '.2f')} ms · {row.model} model"
        + mu1
        + "\n"
        + conditions(row)
        + (f"\n{notes}" if notes else "")
        + (f"\n{f.message}" if f.message else "")
    )
