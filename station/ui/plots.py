"""Plots drawn with text: residuals per photocell, and speed along the run.

Pure functions from numbers to lines of text, so they are tested like any other function and
drawn by any widget. Eighth-block characters give eight levels per character cell.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from station.model.fit_result import FitResult
from station.session.analysis import DescentResult

BLOCKS = " ▁▂▃▄▅▆▇█"


def _bar_cell(level: float, row_from_bottom: int) -> str:
    """The character of a bar of height ``level`` (in rows) at a row counted from its base."""
    fill = level - row_from_bottom
    if fill <= 0:
        return " "
    if fill >= 1:
        return "█"
    return BLOCKS[max(1, round(fill * 8))]


def _hanging_cell(level: float, row_from_top: int) -> str:
    """A bar hanging down from the zero line (fonts have few upper blocks: three levels)."""
    fill = level - row_from_top
    if fill >= 1:
        return "█"
    if fill >= 0.5:
        return "▀"
    return "▔" if fill > 0 else " "


def residual_plot(
    ids: Sequence[str], residuals_ms: Sequence[float], height: int = 6, bar_width: int = 4
) -> list[str]:
    """Bars up (computed later than measured) and down around a zero line, one per photocell.

    ``height`` rows in all: half above the zero line, half below. The scale is printed.
    Each photocell takes ``bar_width`` columns (at least its name and a space).
    """
    half = max(1, (height - 2) // 2)
    finite = [abs(r) for r in residuals_ms if math.isfinite(r)]
    scale = max(finite) if finite else 1.0
    scale = scale if scale > 0 else 1.0
    width = max(bar_width, max((len(i) for i in ids), default=3) + 1)
    bar = max(1, (width - 2) // 3)  # the bar's own width: a third of its column
    up = []
    for r in residuals_ms:
        up.append(half * max(r, 0.0) / scale if math.isfinite(r) else 0.0)
    down = [half * max(-r, 0.0) / scale if math.isfinite(r) else 0.0 for r in residuals_ms]
    lines = []
    for row in range(half - 1, -1, -1):
        cells = "".join((_bar_cell(u, row) * bar).center(width) for u in up)
        label = f"+{scale:.2f}" if row == half - 1 else ""
        lines.append(f"{label:>6} {cells}")
    lines.append(f"{'0 ms':>6} " + "".join("─" * (width - 1) + " " for _ in ids))
    for row in range(half):
        cells = "".join((_hanging_cell(d, row) * bar).center(width) for d in down)
        label = f"-{scale:.2f}" if row == half - 1 else ""
        lines.append(f"{label:>6} {cells}")
    lines.append(" " * 7 + "".join(i.center(width) for i in ids))
    return lines


def speed_plot(
    x: Sequence[float], v: Sequence[float], width: int = 40, height: int = 5
) -> list[str]:
    """Speed against distance as a filled profile, ``width`` columns by ``height`` rows."""
    if len(x) < 2:
        return ["(no fit yet)"]
    x0, x1 = float(x[0]), float(x[-1])
    vmax = max(float(max(v)), 1e-9)
    cols = []
    j = 0
    for c in range(width):
        xc = x0 + (x1 - x0) * (c + 0.5) / width
        while j < len(x) - 2 and x[j + 1] < xc:
            j += 1
        t = (xc - x[j]) / (x[j + 1] - x[j]) if x[j + 1] != x[j] else 0.0
        cols.append(float(v[j]) + t * (float(v[j + 1]) - float(v[j])))
    levels = [height * c / vmax for c in cols]
    lines = []
    for row in range(height - 1, -1, -1):
        label = f"{vmax * 3.6:5.0f}" if row == height - 1 else ("km/h " if row == 0 else "")
        lines.append(f"{label:>5} " + "".join(_bar_cell(lv, row) for lv in levels))
    lines.append(f"{'':5} {x0:<8.0f}{'x [m]':^{max(width - 16, 1)}}{x1:>8.0f}")
    return lines


def residual_text(fit: FitResult, left: int, rows: int) -> str:
    """The residual plot of a fit in a panel ``left`` columns wide: wider bars in a wide
    terminal (up to half the panel)."""
    ids = list(fit.residuals_s)
    bar = max(4, min(10, (left // 2 - 7) // max(len(ids), 1)))
    res_ms = [r * 1000 for r in fit.residuals_s.values()]
    lines = residual_plot(ids, res_ms, height=rows, bar_width=bar)
    return "\n".join(lines) if ids else "no residuals: " + fit.status


def speed_text(res: DescentResult, width: int, height: int) -> str:
    """The fitted speed along the run of a result that carries its curve."""
    if res.speed_x is None or res.speed_v is None:
        return "(no speed profile)"
    x, v = res.speed_x.tolist(), res.speed_v.tolist()
    return "\n".join(speed_plot(x, v, width=width, height=height))
