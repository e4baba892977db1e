"""The day report: one self-contained HTML page with the pictures of a test day, for the coach
and the ski maker who were not at the trackside.

Sections, each with one picture: the track profile with its photocells (the survey's own
picture, :mod:`station.report.track_plot`); every descent's residuals and speed; μ and CdA of
every descent over the time of day with their 90 % intervals; the comparison of the items
(joint fit: μ per item, Δμ to the reference, drift, ranking). Then
the session's metadata and provenance: station version, config and survey with their digests,
what the timer sent, every descent in a table, and the warnings.

The page is one file: pictures are PNG embedded as base64 ``data:`` URIs, styles inline, no
script, no external URL, so it can be mailed, archived, or opened on a laptop without network.
matplotlib is imported inside the drawing functions (``station`` commands that do not draw do
not load it), through its object API (``Figure``) so no GUI backend or global state is touched.
"""

from __future__ import annotations

import base64
import datetime as dt
import html
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from station import __version__
from station.model.estimate import MISSING, Estimate

if TYPE_CHECKING:
    from station.model.compare import JointResult
    from station.session.comparison import DayComparison

#: colours of the test items, in order of their first descent (matplotlib's tab10)
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
           "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]  # fmt: skip
GREY = "#9a9a9a"
DPI = 100
WIDTH_IN = 11.0


@dataclass(frozen=True)
class Section:
    """One part of the page: a heading, text, at most one picture, then tables."""

    id: str
    title: str
    intro: str  # HTML
    figure: str | None = None  # data: URI of a PNG
    alt: str = ""
    after: str = ""  # HTML
    folded: str = ""  # when set, the picture is folded under this summary (<details>)


@dataclass(frozen=True)
class DescentView:
    """What the report shows of one descent. The report reads descents only through these
    records, made in one place (:func:`descent_views`) from the replayed day, so a change in
    how the session code keeps its results touches one function here."""

    number: int
    start_time: str  # ISO 8601, as in the results CSV
    start_hours: float  # the timer's time of day at the start, hours (unwrapped)
    item: str
    status: str  # the fit's status, or the descent's when it was not fitted
    descent_status: str  # complete, incomplete, aborted
    invalid_reason: str
    notes: str
    flags: str
    photocells_used: int
    mu: Estimate
    cda: Estimate
    v0: Estimate
    residuals_ms: dict[str, float]  # photocell -> computed − measured, ms
    rms_ms: float | None
    speed_x: np.ndarray | None = None
    speed_v: np.ndarray | None = None

    @property
    def fitted(self) -> bool:
        return bool(self.residuals_ms)

    @property
    def good(self) -> bool:
        """Valid and fitted ok: drawn in its item's colour."""
        return self.status == "ok" and not self.invalid_reason


@dataclass
class DayData:
    """What the report is drawn from: the day's descents and track, its comparison, and where
    it came from."""

    session: str
    track: Any  # station.survey.track.Track
    descents: list[DescentView]
    header: dict[str, str] = field(default_factory=dict)  # what the results were computed from
    summary: str = ""  # what the timer sent
    config_metadata: dict[str, Any] = field(default_factory=dict)
    #: the day's comparison with its decisions (None: not computed)
    day_comparison: DayComparison | None = None
    config_text: str = ""
    recorded: str = ""  # local date and time the recording began
    annotations: int = 0
    warnings: list[str] = field(default_factory=list)

    @property
    def comparison(self) -> JointResult | None:
        return None if self.day_comparison is None else self.day_comparison.result

    @property
    def comparison_error(self) -> str | None:
        return None if self.day_comparison is None else self.day_comparison.error or None

    @property
    def compared(self) -> list[Any]:
        """The descents (DescentData) that entered the joint fit (none without one)."""
        dc = self.day_comparison
        return [] if dc is None or dc.result is None else dc.compared


def descent_views(results: Sequence[Any]) -> list[DescentView]:
    """The report's records of a replayed day's results
    (:class:`station.session.analysis.DescentResult`: descent times, fit, typed row, speed)."""
    from station.model.compare import item_of

    out = []
    for r in results:
        d, f, row = r.descent, r.fit, r.row
        out.append(
            DescentView(
                number=row.descent,
                start_time=str(row.start_time),
                start_hours=d.start_us / 3.6e9,  # a descent whose times were all cleared has none
                item=item_of(row),
                status=str(row.status),
                descent_status=str(row.descent_status),
                invalid_reason=row.invalid_reason or "",
                notes=row.notes,
                flags="; ".join(row.flags),
                photocells_used=row.photocells_used,
                mu=f.mu if f else MISSING,
                cda=f.cda if f else MISSING,
                v0=f.v0 if f else MISSING,
                residuals_ms={k: v * 1000 for k, v in f.residuals_s.items()} if f else {},
                rms_ms=row.rms_residual_ms,
                speed_x=r.speed_x,
                speed_v=r.speed_v,
            )
        )
    return out


# ----------------------------------------------------------------------------- pictures


def _png(fig, tight: bool = True, dpi: int = DPI) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight" if tight else None,
                metadata={"Software": None})  # fmt: skip
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def _figure(height_in: float, layout: Literal["constrained", "tight"] | None = "constrained"):
    from matplotlib.figure import Figure

    return Figure(figsize=(WIDTH_IN, height_in), layout=layout)


def _style(ax) -> None:
    ax.grid(True, color="#e4e4e4", linewidth=0.8)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)


def _plain(text: Any) -> str:
    """A name as matplotlib should draw it: as typed (``$…$`` would be read as math, and a
    name like ``wax $5 $10`` would end the report in a parse error)."""
    return str(text).replace("$", r"\$")


def item_colours(items: Sequence[str]) -> dict[str, str]:
    return {it: PALETTE[k % len(PALETTE)] for k, it in enumerate(items)}


def profile_figure(track) -> str:
    """The survey's own picture of the track (:func:`station.report.track_plot.track_figure`:
    heights with the points used and left out and the photocells, the points' residuals,
    slope and curvature), drawn once for ``station survey --plot`` and for this page, here in
    memory (no temporary file)."""
    from station.report.track_plot import track_figure

    return _png(track_figure(track), tight=False, dpi=120)  # laid out by the track's picture


#: the residual picture: its height (inches, the same for 8 descents and for 2000) and how
#: many of its rows are labelled at most
ROWS_IN = 3.0
MAX_ROW_LABELS = 16


def residual_matrix(descents: Sequence[DescentView], photocells: Sequence[str]) -> np.ndarray:
    """Residuals (ms) of each descent (rows) at each photocell (columns), NaN where it has
    none (a photocell it missed, a descent not fitted)."""
    col = {p: k for k, p in enumerate(photocells)}
    m = np.full((len(descents), len(photocells)), np.nan)
    for i, d in enumerate(descents):
        for p, r in d.residuals_ms.items():
            if p in col:
                m[i, col[p]] = r
    return m


def descents_figure(
    descents: Sequence[DescentView], colours: dict[str, str], pc_x: dict[str, float]
) -> str:
    """Every descent in one picture whose cost does not grow with the day. Top: the residual
    of each descent (rows, first at the top) at each photocell (columns) as a colour (blue:
    the model is early, red: late; grey: none), a strip in the item's colour (grey: invalid
    or not ok) and each descent's RMS. Bottom: the fitted speed of every descent along the
    run, in its item's colour. A column of one colour is a photocell or survey error; a row,
    a descent the model does not describe (wind, posture).

    One image and a few collections, not an Axes per descent: 50 small panels with their own
    ticks and twin axes took ~55 ms per descent, most of the report's time."""
    from matplotlib.collections import LineCollection
    from matplotlib.colors import to_rgb

    pcs = sorted(pc_x, key=lambda p: pc_x[p])
    m = residual_matrix(descents, pcs)
    finite = np.abs(m[np.isfinite(m)])
    lim = max(float(finite.max()) if finite.size else 0.0, 0.1)
    rows_in = ROWS_IN
    speed_in = 2.4
    height = rows_in + speed_in + 1.5
    fig = _figure(height, layout=None)
    h = 1.0 / height  # one inch, in figure coordinates
    y_rows = 1 - 0.45 * h - rows_in * h
    strip = fig.add_axes((0.06, y_rows, 0.015, rows_in * h))
    heat = fig.add_axes((0.085, y_rows, 0.7, rows_in * h), sharey=strip)
    rms_ax = fig.add_axes((0.8, y_rows, 0.13, rows_in * h), sharey=strip)
    cbar = fig.add_axes((0.945, y_rows, 0.012, rows_in * h))
    sp = fig.add_axes((0.085, 0.5 * h, 0.7, speed_in * h))

    cmap = _residual_cmap()
    im = heat.imshow(m if len(descents) else np.full((1, len(pcs)), np.nan), cmap=cmap,
                     vmin=-lim, vmax=lim, aspect="auto", interpolation="nearest")  # fmt: skip
    heat.set_xticks(range(len(pcs)), pcs, fontsize=8)
    heat.xaxis.set_ticks_position("top")
    heat.tick_params(axis="y", labelleft=False, length=0)
    fig.colorbar(im, cax=cbar)
    cbar.tick_params(labelsize=7)
    cbar.set_ylabel("computed − measured [ms]", fontsize=8)

    rgb = np.array([[to_rgb(colours.get(d.item, GREY) if d.good else GREY)]
                    for d in descents] or [[to_rgb(GREY)]])  # fmt: skip
    strip.imshow(rgb, aspect="auto", interpolation="nearest")
    step = max(1, math.ceil(len(descents) / MAX_ROW_LABELS))
    rows = list(range(0, len(descents), step))
    strip.set_yticks(rows, [str(descents[i].number) for i in rows], fontsize=8)
    strip.set_xticks([])
    strip.set_ylabel("descent", fontsize=8)

    y = np.arange(len(descents))
    r = np.array([np.nan if d.rms_ms is None else d.rms_ms for d in descents], dtype=float)
    rms_ax.plot(r, y, "o-", color="#555555", ms=3, linewidth=0.8)
    rms_ax.set_xlim(0, max(float(np.nanmax(r)) if np.isfinite(r).any() else 0.0, 0.1) * 1.15)
    rms_ax.tick_params(axis="y", labelleft=False, length=0)
    rms_ax.tick_params(axis="x", labelsize=7)
    rms_ax.xaxis.set_ticks_position("top")
    rms_ax.set_title("RMS [ms]", fontsize=8, loc="left")
    _style(rms_ax)
    strip.set_ylim(len(descents) - 0.5 if descents else 0.5, -0.5)

    lines, lcols = [], []
    vmax = 1.0
    for d in descents:
        if d.speed_x is None or d.speed_v is None:
            continue
        lines.append(np.column_stack([d.speed_x, d.speed_v]))
        lcols.append(colours.get(d.item, GREY) if d.good else GREY)
        vmax = max(vmax, float(np.max(d.speed_v)))
    sp.add_collection(LineCollection(lines, colors=lcols, linewidths=1.0, alpha=0.8))
    xs = [pc_x[p] for p in pcs]
    if xs:
        span = max(xs[-1] - xs[0], 1.0)
        sp.set_xlim(xs[0] - 0.02 * span, xs[-1] + 0.02 * span)
    sp.set_ylim(0, vmax * 1.1)
    sp.set_xlabel("x along the run [m]", fontsize=9)
    sp.set_ylabel("fitted speed [m/s]", fontsize=9)
    sp.tick_params(labelsize=8)
    _style(sp)
    return _png(fig, tight=False)  # laid out by hand above: a tight box would draw it twice


def _residual_cmap():
    from matplotlib import colormaps

    return colormaps["RdBu_r"].with_extremes(bad="#e6e6e6")


def _hhmm(h: float, _pos: Any = None) -> str:
    m = int(round(h * 60)) % (24 * 60)
    return f"{m // 60:02d}:{m % 60:02d}"


#: steps of the time-of-day axis, minutes: the first that gives at most MAX_TICKS ticks
MINUTE_STEPS = (1, 2, 5, 10, 15, 20, 30, 60, 120, 180, 240, 360)
MAX_TICKS = 9


def minute_ticks(h0: float, h1: float) -> list[float]:
    """Ticks of a time-of-day axis from ``h0`` to ``h1`` (hours): on whole minutes, evenly
    spaced by a step people count in (5, 10, 15, 30 min …), every one labelled."""
    lo, hi = min(h0, h1) * 60, max(h0, h1) * 60
    for step in MINUTE_STEPS:
        first = math.ceil(lo / step - 1e-9) * step
        count = int(math.floor((hi - first) / step + 1e-9)) + 1
        if count <= MAX_TICKS:
            break
    return [(first + k * step) / 60 for k in range(max(count, 0))]


def drift_reference_hours(compared: Sequence[Any]) -> float | None:
    """The time of day the joint fit's μ per item refers to when it fits a drift: the mean
    start time of the descents compared (μ = μ_item + drift·(t − t̄))."""
    return float(np.mean([d.start_hours for d in compared])) if compared else None


#: the μ points carry their descent's number up to this many descents
MAX_NUMBERED = 80


def time_of_day_figure(descents: Sequence[DescentView], colours: dict[str, str],
                       comparison=None, compared: Sequence[Any] = ()) -> str:  # fmt: skip
    """μ and CdA of each descent against its start time with 90 % intervals; the joint fit's
    μ per item (with the drift, when fitted) and CdA drawn over them."""
    return _png(time_of_day_axes(descents, colours, comparison, compared), tight=False)


def time_of_day_axes(descents: Sequence[DescentView], colours: dict[str, str],
                     comparison=None, compared: Sequence[Any] = ()):  # fmt: skip
    """The figure of :func:`time_of_day_figure` (a matplotlib ``Figure``). One errorbar per
    item and kind of point, not per descent: the cost does not grow with the day."""
    # laid out by hand: the constrained layout (and a tight box) measure every descent's label
    fig = _figure(5.6, layout=None)
    fig.subplots_adjust(left=0.085, right=0.985, top=0.93, bottom=0.1, hspace=0.22)
    am, ac = fig.subplots(2, 1, sharex=True)
    hours_all: list[float] = []
    groups: dict[tuple[str, bool], list[DescentView]] = {}
    for d in descents:
        if d.mu.value is None:
            continue
        hours_all.append(d.start_hours)
        groups.setdefault((d.item, d.good), []).append(d)
    for (item, good), ds in groups.items():
        colour = colours.get(item, GREY) if good else GREY
        for ax, key in ((am, "mu"), (ac, "cda")):
            pts = [d for d in ds if getattr(d, key).value is not None]
            if not pts:
                continue
            h = np.array([d.start_hours for d in pts])
            v = np.array([getattr(d, key).value for d in pts], dtype=float)
            ci = [getattr(d, key).ci90 for d in pts]
            lo = np.array([v[k] - c[0] if c else 0.0 for k, c in enumerate(ci)])
            hi = np.array([c[1] - v[k] if c else 0.0 for k, c in enumerate(ci)])
            ax.errorbar(h, v, yerr=[lo, hi], fmt="o", color=colour,
                        mfc=colour if good else "white", ms=6, capsize=3,
                        linewidth=1.2)  # fmt: skip
        for d in ds if len(hours_all) <= MAX_NUMBERED else ():  # a long day: a smear of text
            am.annotate(str(d.number), (d.start_hours, d.mu.value),
                        textcoords="offset points", xytext=(5, 3), fontsize=7,
                        color="#555555")  # fmt: skip
    t_ref = drift_reference_hours(compared)
    if comparison is not None and hours_all:
        t0, t1 = min(hours_all), max(hours_all)
        pad = max((t1 - t0) * 0.03, 1 / 60)
        hx = np.array([t0 - pad, t1 + pad])
        drift = comparison.drift_per_hour[0] if comparison.drift_per_hour else 0.0
        ref = t_ref if t_ref is not None else 0.0
        for it in comparison.items:
            am.plot(hx, it.mu + drift * (hx - ref), "--", color=colours.get(it.item, GREY),
                    linewidth=1.0)  # fmt: skip
        if comparison.drift_per_hour and t_ref is not None:
            am.axvline(t_ref, color="#999999", linestyle=":", linewidth=1.0)
            am.annotate(f"t̄ {_hhmm(t_ref)}", (t_ref, 1.0), xycoords=("data", "axes fraction"),
                        xytext=(3, -10), textcoords="offset points", fontsize=7,
                        color="#555555")  # fmt: skip
        for cda in comparison.cda.values():
            ac.axhline(cda.value, color="#333333", linestyle="--", linewidth=1.0)
            if cda.ci90 is not None:
                ac.axhspan(cda.ci90[0], cda.ci90[1], color="#333333", alpha=0.08)
    for it, colour in colours.items():
        am.plot([], [], "o", color=colour, label=_plain(it))
    am.plot([], [], "o", color=GREY, mfc="white", label="invalid or not ok")
    if comparison is not None:
        label = "joint fit μ per item"
        if comparison.drift_per_hour and t_ref is not None:
            label += f" with the drift (μ at t̄ = {_hhmm(t_ref)})"
        am.plot([], [], "--", color="#555555", label=label)
        ac.plot([], [], "--", color="#333333", label="joint fit CdA (band: 90 % interval)")
        ac.legend(loc="lower left", bbox_to_anchor=(0, 1.0), frameon=False, fontsize=8)
    am.legend(loc="lower left", bbox_to_anchor=(0, 1.0), frameon=False, fontsize=8, ncol=4)
    am.set_ylabel("μ (90 % interval)")
    ac.set_ylabel("CdA [m²] (90 % interval)")
    ac.set_xlabel("start time (timer's time of day, hh:mm)")
    if hours_all:
        t0, t1 = min(hours_all), max(hours_all)
        pad = max((t1 - t0) * 0.04, 1 / 60)
        ac.set_xlim(t0 - pad, t1 + pad)
        ac.set_xticks(minute_ticks(t0 - pad, t1 + pad))
        ac.xaxis.set_major_formatter(_hhmm_formatter())
    for a in (am, ac):
        _style(a)
    return fig


def _hhmm_formatter():
    from matplotlib.ticker import FuncFormatter

    return FuncFormatter(_hhmm)


def comparison_figure(res, colours: dict[str, str]) -> str:
    """Left: μ of each item with its 90 % interval, best on top. Right: Δμ = item − reference
    with its interval, P(faster) and the time it makes over the run; an item that cannot be
    compared (one valid descent) says so instead."""
    from station.model.versus import versus

    fig = _figure(0.45 * len(res.ranking) + 1.0)
    left, right = fig.subplots(1, 2, sharey=True)
    names = list(reversed(res.ranking))  # best at the top
    y = np.arange(len(names))
    by = {i.item: i for i in res.items}
    for k, name in enumerate(names):
        it = by[name]
        c = colours.get(name, GREY)
        left.errorbar([it.mu], [k], xerr=[[it.mu - it.ci90[0]], [it.ci90[1] - it.mu]],
                      fmt="o", color=c, capsize=4, ms=7)  # fmt: skip
        if name == res.reference:
            right.plot([0], [k], "D", color=c, ms=6)
            right.annotate("reference", (0, k), textcoords="offset points", xytext=(8, -3),
                           fontsize=8)  # fmt: skip
            continue
        v = versus(res, name)
        if v is None:
            right.annotate(f"not comparable ({count_valid(it)})", (0, k),
                           textcoords="offset points", xytext=(8, -3), fontsize=8,
                           color="#b00020")  # fmt: skip
            continue
        dm, (lo, hi) = v.delta_mu, v.ci90
        right.errorbar([dm], [k], xerr=[[dm - lo], [hi - dm]], fmt="o", color=c, capsize=4,
                       ms=7)  # fmt: skip
        right.annotate(f"P(faster) {v.p_faster:.2f}, {v.delta_t_s * 1000:+.0f} ms",
                       (hi, k), textcoords="offset points", xytext=(6, -3), fontsize=8)  # fmt: skip
    right.axvline(0, color="#555555", linewidth=0.8)
    left.set_yticks(y, [f"{len(names) - k}. {_plain(n)}" for k, n in enumerate(names)])
    left.set_ylim(-0.6, len(names) - 0.4)
    left.set_xlabel("μ of the item (joint fit), 90 % interval")
    right.set_xlabel(f"Δμ = item − {_plain(res.reference)}  (< 0: glides better)")
    lo_x, hi_x = right.get_xlim()
    right.set_xlim(lo_x, hi_x + 0.45 * (hi_x - lo_x))  # room for the labels
    for a in (left, right):
        _style(a)
    return _png(fig)


def count_valid(it) -> str:
    n = len(it.descents)
    return f"{n} valid descent{'s' * (n != 1)}"


# ----------------------------------------------------------------------------- page


def _e(v: Any) -> str:
    return html.escape("" if v is None else str(v))


def _num(v: Any, spec: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    return format(v, spec)


def _table(head: Sequence[str] | None, rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    out = [f'<table class="{cls}">']
    if head:
        out += ["<thead><tr>", *(f"<th>{_e(h)}</th>" for h in head), "</tr></thead>"]
    out.append("<tbody>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{_e(c)}</td>" for c in row) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _descent_rows(descents: Sequence[DescentView]) -> list[list[str]]:
    def rng(est: Estimate, spec: str) -> str:
        v, c = est.value, est.ci90
        if v is None:
            return "—"
        return f"{format(v, spec)} [{format(c[0], spec)}, {format(c[1], spec)}]" if c else (
            format(v, spec))  # fmt: skip

    return [
        [str(d.number), d.start_time.replace("T", " ")[:19], d.item, rng(d.mu, ".5f"),
         rng(d.cda, ".4f"), _num(d.v0.value, ".2f"), _num(d.rms_ms, ".2f"),
         str(d.photocells_used), d.status,
         "; ".join(x for x in (d.invalid_reason and f"invalid: {d.invalid_reason}", d.notes,
                               d.flags) if x)]
        for d in descents
    ]  # fmt: skip


CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.2em auto;
       max-width: 1150px; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; margin: 0 0 0.1em 0; }
h2 { font-size: 1.25em; border-bottom: 2px solid #ddd; padding-bottom: 0.2em; margin-top: 1.6em; }
.sub { color: #666; margin-top: 0; font-size: 0.9em; }
img { max-width: 100%; height: auto; display: block; margin: 0.8em 0; }
table { border-collapse: collapse; font-size: 0.88em; margin: 0.8em 0; }
section { overflow-x: auto; }  /* a table of long item names scrolls, not the whole page */
th, td { border-bottom: 1px solid #e2e2e2; padding: 0.25em 0.7em; text-align: left;
         vertical-align: top; }
th { background: #f4f4f4; }
td { font-variant-numeric: tabular-nums; white-space: nowrap; }
td:last-child { white-space: normal; }
.warn { background: #fff4e5; border-left: 4px solid #f0a020; padding: 0.4em 0.8em; }
.err { background: #fdecea; border-left: 4px solid #d62728; padding: 0.4em 0.8em; }
pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
nav a { margin-right: 1em; }
#verdict h2 { margin-top: 0.8em; }
ul.verdicts { list-style: none; padding: 0; margin: 0.5em 0; }
ul.verdicts li { padding: 0.45em 0.8em; margin: 0.35em 0; border-left: 5px solid #9a9a9a;
                 background: #f7f7f7; font-size: 1.05em; }
ul.verdicts li.decided { border-left-color: #2ca02c; background: #eef7ee; }
ul.verdicts li.open { border-left-color: #f0a020; background: #fff7ea; }
ul.verdicts li.none { border-left-color: #9a9a9a; }
.numbers { font-variant-numeric: tabular-nums; }
details > summary { cursor: pointer; font-weight: 600; margin: 0.6em 0; }
@media print { h2 { page-break-before: auto; } img { page-break-inside: avoid; }
               details { display: block; } }
"""


def render_html(title: str, subtitle: str, sections: Sequence[Section]) -> str:
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{_e(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{_e(title)}</h1><p class='sub'>{_e(subtitle)}</p>",
        "<nav>" + "".join(f'<a href="#{s.id}">{_e(s.title)}</a>' for s in sections) + "</nav>",
    ]
    for s in sections:
        parts.append(f'<section id="{s.id}"><h2>{_e(s.title)}</h2>{s.intro}')
        if s.figure:
            img = f'<figure><img src="{s.figure}" alt="{_e(s.alt)}"></figure>'
            if s.folded:
                img = f"<details><summary>{_e(s.folded)}</summary>{img}</details>"
            parts.append(img)
        parts.append(f"{s.after}</section>")
    parts.append(f"<footer><p class='sub'>station {_e(__version__)}</p></footer>")
    parts.append("</body></html>")
    return "\n".join(parts)


def build_day_report(day: DayData) -> str:
    """The page of one test day: the answer first (a verdict per comparison, then μ and CdA
    over the day), then the comparison's detail, the track, every descent's residuals (folded)
    and the provenance."""
    from station.report.comparison_text import format_comparison

    track = day.track
    descents = day.descents
    real = [d for d in descents if d.descent_status != "aborted"]
    colours = item_colours(list(dict.fromkeys(d.item for d in real)))
    ok = [d for d in real if d.good]

    sections = [
        _verdict_section(day),
        Section(
            "timeline",
            "μ and CdA over the day",
            "<p>Each descent's own fit with its 90 % interval, against its start time. "
            "Hollow grey points are invalid or not ok. Dashed: the joint fit of the day"
            + _drift_words(day)
            + ".</p>",
            time_of_day_figure(descents, colours, day.comparison, day.compared) if real else None,
            "friction and drag area of each descent over the time of day",
        ),
        _comparison_section(day, colours, format_comparison),
        Section(
            "track",
            "Track profile and photocells",
            f"<p>{_e(track.name)}: {len(track.photocells)} photocells over "
            f"{track.length_m:.1f} m along the track, {track.drop_m:.1f} m drop; spline residual "
            f"RMS {track.residual_rms_m * 1000:.1f} mm.</p>",
            profile_figure(track),
            "track profile with photocells",
        ),
        Section(
            "descents",
            "Descents: residuals and speed",
            f"<p>{len(real)} descents ({len(ok)} ok and valid). One row per descent: the fit's "
            "residual at each photocell (computed − measured time, bars) and its RMS; below, "
            "the fitted speed along the run. Residuals larger than a few tenths of a "
            "millisecond, or a pattern along the run, point at a photocell, a gust or a skier "
            "who did not hold the tuck.</p>",
            descents_figure(descents, colours, {pc.id: pc.x for pc in track.photocells})
            if descents
            else None,
            "residuals and speed of each descent",
            folded=f"the residuals of {len(descents)} descent{'s' * (len(descents) != 1)}",
        ),
        _provenance_section(day),
    ]
    recorded = day.recorded or (descents[0].start_time[:10] if descents else "")
    title = f"Test day {recorded[:10]} — {track.name}".strip()
    subtitle = (f"session {os.path.basename(os.path.normpath(day.session))}; "
                f"report made {dt.datetime.now().astimezone().isoformat(timespec='seconds')} "
                f"by station {__version__}")  # fmt: skip
    return render_html(title, subtitle, sections)


@dataclass(frozen=True)
class Verdict:
    """The answer to one comparison, in words: what the page says first."""

    kind: str  # decided | open | none (not comparable)
    html: str


def verdicts(day: DayComparison) -> list[Verdict]:
    """One headline per item against the reference: which is faster, Δμ with its 90 %
    interval, the time it makes over the run, how sure, how many descents, decided or not.
    Decided or not is the day comparison's own decision, the one ``station compare``, the UI
    and the console give: a poor fit or a drift not separable from the pair decides nothing."""
    from station.model.versus import versus
    from station.report.comparison_text import decision_words

    res = day.result
    assert res is not None
    out: list[Verdict] = []
    by = {i.item: i for i in res.items}
    ref = res.reference
    for name in res.ranking:
        if name == ref:
            continue
        it = by[name]
        v = versus(res, name)
        if v is None:
            why = count_valid(it) if len(it.descents) < 2 else "no interval"
            if ref in by and len(by[ref].descents) < 2:
                why = ("" if why == "no interval" else why + "; ") + (
                    f"the reference {_e(ref)}: {count_valid(by[ref])}"
                )
            out.append(Verdict("none", f"<b>{_e(name)}</b> against <b>{_e(ref)}</b>: "
                                       f"not comparable ({why})"))  # fmt: skip
            continue
        cmp = v.comparison
        dm, (lo, hi) = v.delta_mu, v.ci90
        item_better = dm < 0
        better, worse = (name, ref) if item_better else (ref, name)
        # in words, the better item first: Δμ = worse − better > 0 and the time it gains
        by_mu, by_lo, by_hi = (-dm, -hi, -lo) if item_better else (dm, lo, hi)
        p_better = v.p_faster if item_better else 1.0 - v.p_faster
        gain_ms = abs(cmp.delta_t_s) * 1000
        n_ref = len(by[ref].descents) if ref in by else 0
        sure = "> 0.999" if p_better > 0.999 else f"{p_better:.3f}"
        numbers = (
            f"by Δμ {by_mu:.5f} [{by_lo:+.5f}, {by_hi:+.5f}] (90 %), {gain_ms:.1f} ms over the "
            f"run at v0 {res.typical_v0:.1f} m/s; P({_e(better)} faster) {sure}; "
            f"{len(it.descents)} descents of {_e(name)}, {n_ref} of {_e(ref)}"
        )
        decision = day.decision(cmp)
        assert decision is not None
        if decision.state == "decided":
            head = f"<b>{_e(better)}</b> glides better than <b>{_e(worse)}</b>"
            r_lo, r_hi = sorted(abs(x) for x in decision.interval or (lo, hi))
            tail = (f"<b>decided</b>: the interval widened for a look after every "
                    f"descent, [{r_lo:+.5f}, {r_hi:+.5f}], excludes 0, as station compare "
                    "decides")  # fmt: skip
            kind = "decided"
        else:
            head = f"<b>{_e(better)}</b> ahead of <b>{_e(worse)}</b>"
            why = decision_words(decision).removeprefix("not yet: ")
            if not decision.reason and (lo > 0 or hi < 0):
                why = f"the 90 % interval excludes 0 but not yet at this look's boundary; {why}"
            tail = f"<b>not decided</b>: {_e(why)}"
            kind = "open"
        out.append(Verdict(kind, f"{head} <span class='numbers'>{numbers}</span>. {tail}."))
    if len(res.items) == 1:
        it = res.items[0]
        out.append(Verdict("none", f"one item only (<b>{_e(it.item)}</b>, "
                                   f"{count_valid(it)}): nothing to compare"))  # fmt: skip
    return out


def _drift_words(day: DayData) -> str:
    res = day.comparison
    if res is None or not res.drift_per_hour:
        return ""
    t_ref = drift_reference_hours(day.compared)
    if t_ref is None:
        return ""
    return (f", with the drift of μ over the day; each item's μ is its value at "
            f"{_hhmm(t_ref)} (timer's time of day), the mean start time of the "
            f"{len(day.compared)} compared descents")  # fmt: skip


def _verdict_section(day: DayData) -> Section:
    """The answer, first on the page."""
    res = day.comparison
    if res is None:
        return Section("verdict", "Verdict",
                       f"<p class='err'>No comparison: {_e(day.comparison_error or 'no data')}"
                       ".</p>")  # fmt: skip
    assert day.day_comparison is not None
    lines = verdicts(day.day_comparison)
    items = "".join(f"<li class='{v.kind}'>{v.html}</li>" for v in lines)
    intro = f"<ul class='verdicts'>{items}</ul>"
    notes = []
    if res.status != "ok":
        notes.append(f"<p class='err'>Joint fit {_e(res.status)}: {_e(res.message)}</p>")
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        t_ref = drift_reference_hours(day.compared)
        when = ""
        if t_ref is not None:
            when = f" (μ of each item at {_hhmm(t_ref)}, the compared descents' mean start)"
        apart = "" if res.drift_separable else " — <b>not separable from the items</b>"
        notes.append(
            f"<p>Drift of μ over the day {d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]"
            f"{_e(when)}{apart}.</p>"
        )
    left_out = len(res.excluded)
    notes.append(f"<p class='sub'>Joint fit of {len(day.compared)} valid descents"
                 + (f"; {left_out} left out (see the comparison)" if left_out else "")
                 + f"; reference {_e(res.reference)}.</p>")  # fmt: skip
    return Section("verdict", "Verdict", intro + "".join(notes))


def _comparison_section(day: DayData, colours: dict[str, str], format_comparison) -> Section:
    res = day.comparison
    if res is None:
        return Section(
            "comparison",
            "Comparison of the items",
            f"<p class='err'>No comparison: {_e(day.comparison_error or 'no data')}.</p>",
        )
    from station.model.versus import versus

    rows = []
    by = {i.item: i for i in res.items}
    for k, name in enumerate(res.ranking, start=1):
        it = by[name]
        v = versus(res, name)
        if name == res.reference:
            delta = p = dtime = "reference"
        elif v is None:
            delta, p, dtime = f"not comparable ({count_valid(it)})", "—", "—"
        else:
            delta = f"{v.delta_mu:+.5f} [{v.ci90[0]:+.5f}, {v.ci90[1]:+.5f}]"
            p = f"{v.p_faster:.3f}"
            dtime = f"{v.delta_t_s * 1000:+.1f}"
        rows.append([k, name, len(it.descents), f"{it.mu:.5f}",
                     f"[{it.ci90[0]:.5f}, {it.ci90[1]:.5f}]", delta, p, dtime])  # fmt: skip
    drift = "not fitted"
    t_ref = drift_reference_hours(day.compared)
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        drift = (
            f"{d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]"
            + (f", μ of each item at {_hhmm(t_ref)}" if t_ref is not None else "")
            + ("" if res.drift_separable else " — NOT separable from the items")
        )
    cda = "; ".join(f"{_e(g)} {e.value:.4f} m²" + (f" [{e.lo:.4f}, {e.hi:.4f}]" if e.ci90 else
                    " (fixed)") for g, e in res.cda.items())  # fmt: skip
    notes = "".join(f"<p class='warn'>{_e(w)}</p>" for w in res.warnings)
    left_out = "".join(f"<li>descent {n}: {_e(why)}</li>" for n, why in res.excluded)
    # the model as it is fitted (compare.py): each descent's drag area varies about its
    # skier's by the posture scatter, and each descent has its own v0 and time offset
    from station.report.comparison_text import posture_words

    posture = posture_words(res)
    intro = (
        f"<p>Joint fit of {len(day.compared)} descents: one μ per item, one CdA per skier about "
        "which each descent's drag area varies by the posture scatter, one v0 and one time "
        f"offset at the first photocell per descent"
        f"{', and a drift of μ over the day' if res.drift_per_hour else ''}; "
        f"{res.dof} degrees of freedom, timing residual {res.sigma_s * 1000:.2f} ms, "
        f"status {_e(res.status)}.</p><p>Drift of μ: {_e(drift)}. CdA: {cda}. Posture scatter "
        f"(CdA between descents of a skier): {_e(posture)}.</p>{notes}"
    )
    mu_head = f"μ at {_hhmm(t_ref)}" if res.drift_per_hour and t_ref is not None else "μ"
    after = _table(["rank", "item", "descents", mu_head, "90 % interval",
                    f"Δμ vs {res.reference}", "P(faster than reference)",
                    "Δt over the run [ms]"], rows)  # fmt: skip
    if left_out:
        after += f"<p>Left out of the comparison:</p><ul>{left_out}</ul>"
    after += f"<details><summary>as the terminal shows it</summary><pre>" \
             f"{_e(format_comparison(res, len(day.compared)))}</pre></details>"  # fmt: skip
    return Section("comparison", "Comparison of the items", intro,
                   comparison_figure(res, colours), "μ per item and difference to the reference",
                   after)  # fmt: skip


def _provenance_section(day: DayData) -> Section:
    # the folder's name, not its absolute path: the page is mailed, and this machine's folders
    # mean nothing to its reader (abspath first: "." and "s/" have their name too)
    name = os.path.basename(os.path.abspath(day.session))
    meta = [("session", name), ("recording began", day.recorded or "—"),
            ("station version", __version__)]  # fmt: skip
    meta += [(k, v) for k, v in day.header.items()]
    meta.append(("timer data", day.summary))
    for key in ("skier", "ski", "wax", "notes"):
        if day.config_metadata.get(key):
            meta.append((f"config {key}", day.config_metadata[key]))
    meta.append(("annotations", f"{day.annotations} entered (metadata, invalid marks, models)"))
    warn = "".join(f"<p class='warn'>{_e(w)}</p>" for w in day.warnings)
    after = _table(None, meta, "meta")
    after += "<h3>Descents</h3>" + _table(
        ["#", "start", "item", "μ [90 %]", "CdA [m²] [90 %]", "v0 [m/s]", "rms [ms]",
         "photocells", "status", "notes"], _descent_rows(day.descents))  # fmt: skip
    if day.config_text:
        after += f"<details><summary>config.yaml of the session</summary><pre>" \
                 f"{_e(day.config_text)}</pre></details>"  # fmt: skip
    return Section("provenance", "Session metadata and provenance", warn, None, "", after)
