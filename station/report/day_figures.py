"""The day report's pictures: the track profile, every descent's residuals and speed, μ and
CdA over the time of day, and the comparison of the items, each a PNG embedded as a base64
``data:`` URI. matplotlib is imported inside the drawing functions (commands that do not draw
do not load it), through its object API (``Figure``) so no GUI backend or global state is
touched."""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from station.report.day_data import DescentView

#: colours of the test items, in order of their first descent (matplotlib's tab10)
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
           "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]  # fmt: skip


GREY = "#9a9a9a"


DPI = 100


WIDTH_IN = 11.0


def png(fig, tight: bool = True, dpi: int = DPI) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight" if tight else None,
                metadata={"Software": None})  # fmt: skip
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def figure(height_in: float, layout: Literal["constrained", "tight"] | None = "constrained"):
    from matplotlib.figure import Figure

    return Figure(figsize=(WIDTH_IN, height_in), layout=layout)


def style(ax) -> None:
    ax.grid(True, color="#e4e4e4", linewidth=0.8)
    ax.set_axisbelow(True)
    for side in ("top", "right"):
        ax.spines[side].set_visible(False)


def plain(text: Any) -> str:
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

    return png(track_figure(track), tight=False, dpi=120)  # laid out by the track's picture


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
    fig = figure(height, layout=None)
    h = 1.0 / height  # one inch, in figure coordinates
    y_rows = 1 - 0.45 * h - rows_in * h
    strip = fig.add_axes((0.06, y_rows, 0.015, rows_in * h))
    heat = fig.add_axes((0.085, y_rows, 0.7, rows_in * h), sharey=strip)
    rms_ax = fig.add_axes((0.8, y_rows, 0.13, rows_in * h), sharey=strip)
    cbar = fig.add_axes((0.945, y_rows, 0.012, rows_in * h))
    sp = fig.add_axes((0.085, 0.5 * h, 0.7, speed_in * h))

    cmap = residual_cmap()
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
    style(rms_ax)
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
    style(sp)
    return png(fig, tight=False)  # laid out by hand above: a tight box would draw it twice


def residual_cmap():
    from matplotlib import colormaps

    return colormaps["RdBu_r"].with_extremes(bad="#e6e6e6")


def hhmm(h: float, _pos: Any = None) -> str:
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
    return png(time_of_day_axes(descents, colours, comparison, compared), tight=False)


def time_of_day_axes(descents: Sequence[DescentView], colours: dict[str, str],
                     comparison=None, compared: Sequence[Any] = ()):  # fmt: skip
    """The figure of :func:`time_of_day_figure` (a matplotlib ``Figure``). One errorbar per
    item and kind of point, not per descent: the cost does not grow with the day."""
    # laid out by hand: the constrained layout (and a tight box) measure every descent's label
    fig = figure(5.6, layout=None)
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
            am.annotate(f"t̄ {hhmm(t_ref)}", (t_ref, 1.0), xycoords=("data", "axes fraction"),
                        xytext=(3, -10), textcoords="offset points", fontsize=7,
                        color="#555555")  # fmt: skip
        for cda in comparison.cda.values():
            ac.axhline(cda.value, color="#333333", linestyle="--", linewidth=1.0)
            if cda.ci90 is not None:
                ac.axhspan(cda.ci90[0], cda.ci90[1], color="#333333", alpha=0.08)
    for it, colour in colours.items():
        am.plot([], [], "o", color=colour, label=plain(it))
    am.plot([], [], "o", color=GREY, mfc="white", label="invalid or not ok")
    if comparison is not None:
        label = "joint fit μ per item"
        if comparison.drift_per_hour and t_ref is not None:
            label += f" with the drift (μ at t̄ = {hhmm(t_ref)})"
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
        ac.xaxis.set_major_formatter(hhmm_formatter())
    for a in (am, ac):
        style(a)
    return fig


def hhmm_formatter():
    from matplotlib.ticker import FuncFormatter

    return FuncFormatter(hhmm)


def comparison_figure(res, colours: dict[str, str]) -> str:
    """Left: μ of each item with its 90 % interval, best on top. Right: Δμ = item − reference
    with its interval, P(faster) and the time it makes over the run; an item that cannot be
    compared (one valid descent) says so instead."""
    from station.model.versus import versus

    fig = figure(0.45 * len(res.ranking) + 1.0)
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
    left.set_yticks(y, [f"{len(names) - k}. {plain(n)}" for k, n in enumerate(names)])
    left.set_ylim(-0.6, len(names) - 0.4)
    left.set_xlabel("μ of the item (joint fit), 90 % interval")
    right.set_xlabel(f"Δμ = item − {plain(res.reference)}  (< 0: glides better)")
    lo_x, hi_x = right.get_xlim()
    right.set_xlim(lo_x, hi_x + 0.45 * (hi_x - lo_x))  # room for the labels
    for a in (left, right):
        style(a)
    return png(fig)


def count_valid(it) -> str:
    n = len(it.descents)
    return f"{n} valid descent{'s' * (n != 1)}"
