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
    comparison: JointResult | None = None
    comparison_error: str | None = None
    compared: list[Any] = field(default_factory=list)  # DescentData that entered the fit
    config_text: str = ""
    recorded: str = ""  # local date and time the recording began
    annotations: int = 0
    warnings: list[str] = field(default_factory=list)


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


def _png(fig, tight: bool = True) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight" if tight else None,
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


def item_colours(items: Sequence[str]) -> dict[str, str]:
    return {it: PALETTE[k % len(PALETTE)] for k, it in enumerate(items)}


def profile_figure(track) -> str:
    """The survey's own picture of the track (:func:`station.report.track_plot.plot_track`:
    heights with the points used and left out and the photocells, the points' residuals,
    slope and curvature), drawn once for ``station survey --plot`` and for this page."""
    import tempfile

    from station.report.track_plot import plot_track

    with tempfile.TemporaryDirectory(prefix="station-report-") as tmp:
        path = plot_track(track, os.path.join(tmp, "track.png"))
        with open(path, "rb") as fh:
            data = fh.read()
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def descents_figure(
    descents: Sequence[DescentView], colours: dict[str, str], pc_x: dict[str, float]
) -> str:
    """Small multiples, one per descent: residual bars at the photocells (ms, left axis) and
    the fitted skier's speed along the run (m/s, right axis)."""
    n = len(descents)
    cols = 4
    rows = max(1, math.ceil(n / cols))
    # a fixed grid, not the constrained layout: that takes seconds for 50 panels with twins
    height = 2.3 * rows + 0.6
    fig = _figure(height, layout=None)
    fig.subplots_adjust(left=0.07, right=0.95, top=1 - 0.3 / height, bottom=0.5 / height,
                        wspace=0.45, hspace=0.45)  # fmt: skip
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, squeeze=False)).ravel()
    lim = 0.0
    for d in descents:
        lim = max(lim, *(abs(v) for v in d.residuals_ms.values()), 0.0)
    lim = max(lim * 1.15, 0.5)
    vmax = max((float(np.max(d.speed_v)) for d in descents if d.speed_v is not None), default=1.0)
    for ax, d in zip(axes, descents, strict=False):
        colour = colours.get(d.item, GREY)
        status = "invalid" if d.invalid_reason else d.status
        ax.set_title(f"{d.number}  {d.item}  ({status})", loc="left", fontsize=9,
                     color="#b00020" if status not in ("ok",) else "#222222")  # fmt: skip
        _style(ax)
        ax.set_ylim(-lim, lim)
        ax.axhline(0, color="#555555", linewidth=0.8)
        if not d.fitted:
            ax.text(0.5, 0.5, d.status, transform=ax.transAxes, ha="center", va="center",
                    color=GREY)  # fmt: skip
            continue
        bars_x = [pc_x[p] for p in d.residuals_ms]
        bars_ms = list(d.residuals_ms.values())
        ax.bar(bars_x, bars_ms, width=8.0, color=colour if d.good else GREY, alpha=0.85)
        if d.speed_x is not None:
            sp = ax.twinx()
            sp.plot(d.speed_x, d.speed_v, color="#333333", linewidth=1.0)
            sp.set_ylim(0, vmax * 1.1)
            sp.tick_params(labelsize=7)
            sp.spines["top"].set_visible(False)
        ax.tick_params(labelsize=7)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.supylabel("residual, computed − measured [ms] (bars)", fontsize=9)
    fig.supxlabel("x along the run [m];  line: fitted speed [m/s] (right axis)", fontsize=9)
    return _png(fig, tight=False)  # laid out by hand above; a tight box would draw it twice


def _hhmm(h: float, _pos: Any = None) -> str:
    m = int(round(h * 60)) % (24 * 60)
    return f"{m // 60:02d}:{m % 60:02d}"


def time_of_day_figure(descents: Sequence[DescentView], colours: dict[str, str],
                       comparison=None, compared: Sequence[Any] = ()) -> str:  # fmt: skip
    """μ and CdA of each descent against its start time with 90 % intervals; the joint fit's
    μ per item (with the drift, when fitted) and CdA drawn over them."""
    from matplotlib.ticker import FuncFormatter

    fig = _figure(5.6)
    am, ac = fig.subplots(2, 1, sharex=True)
    hours_all = []
    for d in descents:
        if d.mu.value is None:
            continue
        h = d.start_hours
        hours_all.append(h)
        colour = colours.get(d.item, GREY) if not d.invalid_reason else GREY
        face = colour if d.good else "white"
        for ax, est in ((am, d.mu), (ac, d.cda)):
            v = est.value
            if v is None:
                continue
            c = est.ci90
            yerr = None if c is None else [[v - c[0]], [c[1] - v]]
            ax.errorbar([h], [v], yerr=yerr, fmt="o", color=colour, mfc=face, ms=6,
                        capsize=3, linewidth=1.2)  # fmt: skip
            ax.annotate(str(d.number), (h, v), textcoords="offset points",
                        xytext=(5, 3), fontsize=7, color="#555555")  # fmt: skip
    if comparison is not None and hours_all:
        t0, t1 = min(hours_all), max(hours_all)
        pad = max((t1 - t0) * 0.03, 1 / 60)
        hx = np.array([t0 - pad, t1 + pad])
        t_mean = float(np.mean([d.start_hours for d in compared])) if compared else 0.0
        drift = comparison.drift_per_hour[0] if comparison.drift_per_hour else 0.0
        for it in comparison.items:
            am.plot(hx, it.mu + drift * (hx - t_mean), "--", color=colours.get(it.item, GREY),
                    linewidth=1.0)  # fmt: skip
        for cda in comparison.cda.values():
            ac.axhline(cda.value, color="#333333", linestyle="--", linewidth=1.0)
            if cda.ci90 is not None:
                ac.axhspan(cda.ci90[0], cda.ci90[1], color="#333333", alpha=0.08)
    for it, colour in colours.items():
        am.plot([], [], "o", color=colour, label=it)
    am.plot([], [], "o", color=GREY, mfc="white", label="invalid or not ok")
    if comparison is not None:
        am.plot([], [], "--", color="#555555", label="joint fit μ per item (with drift)")
        ac.plot([], [], "--", color="#333333", label="joint fit CdA (band: 90 % interval)")
        ac.legend(loc="lower left", bbox_to_anchor=(0, 1.0), frameon=False, fontsize=8)
    am.legend(loc="lower left", bbox_to_anchor=(0, 1.0), frameon=False, fontsize=8, ncol=4)
    am.set_ylabel("μ (90 % interval)")
    ac.set_ylabel("CdA [m²] (90 % interval)")
    ac.set_xlabel("start time (timer's time of day)")
    ac.xaxis.set_major_formatter(FuncFormatter(_hhmm))
    for a in (am, ac):
        _style(a)
    return _png(fig)


def comparison_figure(res, colours: dict[str, str]) -> str:
    """Left: μ of each item with its 90 % interval, best on top. Right: Δμ = item − reference
    with its interval, P(faster) and the time it makes over the run."""
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
        cmp = next((x for x in res.comparisons if x.a == res.reference and x.b == name), None)
        if cmp is None or cmp.ci90 is None or cmp.p_a_faster is None:  # none possible
            continue
        dm, lo, hi = -cmp.delta_mu, -cmp.ci90[1], -cmp.ci90[0]
        right.errorbar([dm], [k], xerr=[[dm - lo], [hi - dm]], fmt="o", color=c, capsize=4,
                       ms=7)  # fmt: skip
        right.annotate(f"P(faster) {1 - cmp.p_a_faster:.2f}, {-cmp.delta_t_s * 1000:+.0f} ms",
                       (hi, k), textcoords="offset points", xytext=(6, -3), fontsize=8)  # fmt: skip
    right.axvline(0, color="#555555", linewidth=0.8)
    left.set_yticks(y, [f"{len(names) - k}. {n}" for k, n in enumerate(names)])
    left.set_ylim(-0.6, len(names) - 0.4)
    left.set_xlabel("μ of the item (joint fit), 90 % interval")
    right.set_xlabel(f"Δμ = item − {res.reference}  (< 0: glides better)")
    lo_x, hi_x = right.get_xlim()
    right.set_xlim(lo_x, hi_x + 0.45 * (hi_x - lo_x))  # room for the labels
    for a in (left, right):
        _style(a)
    return _png(fig)


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
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 2em auto;
       max-width: 1150px; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; border-bottom: 2px solid #ddd; padding-bottom: 0.2em; margin-top: 2em; }
.sub { color: #666; margin-top: 0; }
img { max-width: 100%; height: auto; display: block; margin: 0.8em 0; }
table { border-collapse: collapse; font-size: 0.88em; margin: 0.8em 0; }
th, td { border-bottom: 1px solid #e2e2e2; padding: 0.25em 0.7em; text-align: left;
         vertical-align: top; }
th { background: #f4f4f4; }
td { font-variant-numeric: tabular-nums; white-space: nowrap; }
td:last-child { white-space: normal; }
.warn { background: #fff4e5; border-left: 4px solid #f0a020; padding: 0.4em 0.8em; }
.err { background: #fdecea; border-left: 4px solid #d62728; padding: 0.4em 0.8em; }
pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
nav a { margin-right: 1em; }
@media print { h2 { page-break-before: auto; } img { page-break-inside: avoid; } }
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
            parts.append(f'<figure><img src="{s.figure}" alt="{_e(s.alt)}"></figure>')
        parts.append(f"{s.after}</section>")
    parts.append(f"<footer><p class='sub'>station {_e(__version__)}</p></footer>")
    parts.append("</body></html>")
    return "\n".join(parts)


def build_day_report(day: DayData) -> str:
    """The page of one test day."""
    from station.model.compare import format_comparison

    track = day.track
    descents = day.descents
    real = [d for d in descents if d.descent_status != "aborted"]
    colours = item_colours(list(dict.fromkeys(d.item for d in real)))
    ok = [d for d in real if d.good]

    sections = [
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
            f"<p>{len(real)} descents ({len(ok)} ok and valid). Each panel: the fit's residual at "
            "each photocell (computed − measured time, bars) and the fitted speed along the run "
            "(line). Residuals larger than a few tenths of a millisecond, or a pattern along the "
            "run, point at a photocell, a gust or a skier who did not hold the tuck.</p>",
            descents_figure(descents, colours, {pc.id: pc.x for pc in track.photocells})
            if descents
            else None,
            "residuals and speed of each descent",
        ),
        Section(
            "timeline",
            "μ and CdA over the day",
            "<p>Each descent's own fit with its 90 % interval, against its start time. "
            "Hollow grey points are invalid or not ok. Dashed: the joint fit of the day.</p>",
            time_of_day_figure(descents, colours, day.comparison, day.compared) if real else None,
            "friction and drag area of each descent over the time of day",
        ),
        _comparison_section(day, colours, format_comparison),
        _provenance_section(day),
    ]
    recorded = day.recorded or (descents[0].start_time[:10] if descents else "")
    title = f"Test day {recorded[:10]} — {track.name}".strip()
    subtitle = (f"session {os.path.basename(os.path.normpath(day.session))}; "
                f"report made {dt.datetime.now().astimezone().isoformat(timespec='seconds')} "
                f"by station {__version__}")  # fmt: skip
    return render_html(title, subtitle, sections)


def _comparison_section(day: DayData, colours: dict[str, str], format_comparison) -> Section:
    res = day.comparison
    if res is None:
        return Section(
            "comparison",
            "Comparison of the items",
            f"<p class='err'>No comparison: {_e(day.comparison_error or 'no data')}.</p>",
        )
    rows = []
    by = {i.item: i for i in res.items}
    for k, name in enumerate(res.ranking, start=1):
        it = by[name]
        cmp = next((c for c in res.comparisons if c.a == res.reference and c.b == name), None)
        if cmp is None:
            delta = p = dtime = "reference" if name == res.reference else "—"
        elif cmp.ci90 is None or cmp.p_a_faster is None:  # an item of one descent
            delta, p, dtime = "no comparison possible", "—", "—"
        else:
            delta = f"{-cmp.delta_mu:+.5f} [{-cmp.ci90[1]:+.5f}, {-cmp.ci90[0]:+.5f}]"
            p = f"{1 - cmp.p_a_faster:.3f}"
            dtime = f"{-cmp.delta_t_s * 1000:+.1f}"
        rows.append([k, name, len(it.descents), f"{it.mu:.5f}",
                     f"[{it.ci90[0]:.5f}, {it.ci90[1]:.5f}]", delta, p, dtime])  # fmt: skip
    drift = "not fitted"
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        drift = f"{d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]" + (
            "" if res.drift_separable else " — NOT separable from the items"
        )
    cda = "; ".join(f"{_e(g)} {e.value:.4f} m²" + (f" [{e.lo:.4f}, {e.hi:.4f}]" if e.ci90 else
                    " (fixed)") for g, e in res.cda.items())  # fmt: skip
    notes = "".join(f"<p class='warn'>{_e(w)}</p>" for w in res.warnings)
    left_out = "".join(f"<li>descent {n}: {_e(why)}</li>" for n, why in res.excluded)
    intro = (
        f"<p>Joint fit of {len(day.compared)} descents: one μ per item, one CdA per skier, one v0 "
        f"per descent{', and a drift of μ over the day' if res.drift_per_hour else ''}; "
        f"{res.dof} degrees of freedom, timing residual {res.sigma_s * 1000:.2f} ms, "
        f"status {_e(res.status)}.</p><p>Drift of μ: {_e(drift)}. CdA: {cda}.</p>{notes}"
    )
    after = _table(["rank", "item", "descents", "μ", "90 % interval", f"Δμ vs {res.reference}",
                    "P(faster than reference)", "Δt over the run [ms]"], rows)  # fmt: skip
    if left_out:
        after += f"<p>Left out of the comparison:</p><ul>{left_out}</ul>"
    after += f"<details><summary>as the terminal shows it</summary><pre>" \
             f"{_e(format_comparison(res, len(day.compared)))}</pre></details>"  # fmt: skip
    return Section("comparison", "Comparison of the items", intro,
                   comparison_figure(res, colours), "μ per item and difference to the reference",
                   after)  # fmt: skip


def _provenance_section(day: DayData) -> Section:
    meta = [("session", os.path.abspath(day.session)), ("recording began", day.recorded or "—"),
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
