"""Crossing times out (issue 11): one row per impulse kept in a descent, the times the fits
were made from, so a day's timing can be checked or refitted elsewhere.

    descent,bib,photocell,channel,time_of_day,t_s,residual_ms
    3,12,PC1,C0,10:15:02.1234,0.0000,
    3,12,PC2,C1,10:15:04.9876,2.8642,0.12

``t_s`` counts from the descent's first photocell; ``residual_ms`` is measured − fitted where
the descent was fitted (blank otherwise, and at the first photocell, which the fit takes as
its origin). Pure formatting plus one writer; no state.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import IO, TYPE_CHECKING

from station import csvfiles
from station.timing.impulses import DAY_US, format_tod

if TYPE_CHECKING:  # a replay without fits (--no-fit) does not load the fit
    from station.session.analysis import DescentResult
    from station.session.records import DescentTimes
TIMES_COLUMNS = ["descent", "bib", "photocell", "channel", "time_of_day", "t_s", "residual_ms"]


def crossing_rows(results: Iterable[DescentResult]) -> list[list[str]]:
    """The rows, by descent number, photocells in order down the run."""
    return [
        row
        for res in sorted(results, key=lambda r: r.descent.number)
        for row in descent_rows(res.descent, res.fit.residuals_s if res.fit is not None else {})
    ]


def descent_rows(d: DescentTimes, resid: Mapping[str, float]) -> list[list[str]]:
    """One descent's rows (``resid``: its fit's residuals by photocell, s; empty: not fitted)."""
    rows: list[list[str]] = []
    for i, (pc, t) in enumerate(zip(d.photocells, d.times_us, strict=True)):
        ch = d.channels[i] if i < len(d.channels) else ""
        r = resid.get(pc) if i > 0 else None
        rows.append([
            str(d.number), d.bib, pc, ch, format_tod(t % DAY_US, 4),
            f"{(t - d.times_us[0]) / 1e6:.4f}", "" if r is None else f"{r * 1000:.3f}",
        ])  # fmt: skip
    return rows


def write_times(results: Iterable[DescentResult], fh: IO[str]) -> int:
    """Write the crossing times CSV into an open text file (``newline=""``; the command opens
    it, or standard output for ``-``); returns the number of rows."""
    return write_rows(crossing_rows(results), fh)


def write_descent_times(descents: Iterable[DescentTimes], fh: IO[str]) -> int:
    """The crossing times of descents not fitted (``station replay --no-fit``)."""
    rows = [r for d in sorted(descents, key=lambda d: d.number) for r in descent_rows(d, {})]
    return write_rows(rows, fh)


def write_rows(rows: list[list[str]], fh: IO[str]) -> int:
    w = csvfiles.writer(fh)  # formula-safe cells (a bib is the timer's text)
    w.writerow(TIMES_COLUMNS)
    w.writerows(rows)
    return len(rows)
