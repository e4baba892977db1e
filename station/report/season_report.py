"""The season on one self-contained HTML page (``station season report``): each item's Δμ
against the reference over the snow temperature of its days, with its 90 % band and the days
as points; the ranking at the conditions asked for; which items met on which day (the network
the comparison rests on); the days with their conditions. Pictures are PNG in ``data:`` URIs,
as in the day's report (:mod:`station.report.day_report`), so the page is one file to mail."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import Any

from station.files import write_atomic
from station.report.day_figures import figure, item_colours, plain, png, style
from station.report.page import Section, esc, num, render_html, table

REPORT = "season.html"


def effects_figure(res: Any, days: Sequence[Any], colours: dict[str, str]) -> str | None:
    """Δμ against the reference over snow temperature: each day where an item met the
    reference is a point (the day's own difference); the band is the season's estimate with its
    90 % interval over the range of temperatures the item was tested at."""
    key = "snow_temperature_c"
    fig = figure(3.6)
    ax = fig.add_subplot()
    style(ax)
    drawn = False
    for it in res.items:
        if it.item == res.reference or it.delta_mu is None or it.ci90 is None:
            continue
        c = colours[it.item]
        xs, ys = [], []
        for d in days:
            if it.item in d.items and res.reference in d.items and key in d.conditions:
                j, r = d.items.index(it.item), d.items.index(res.reference)
                xs.append(d.conditions[key])
                ys.append(float(d.mu[j] - d.mu[r]))
        temps = [d.conditions[key] for d in days if it.item in d.items and key in d.conditions]
        if temps:
            lo, hi = min(temps) - 0.3, max(temps) + 0.3
            ax.fill_between([lo, hi], it.ci90[0], it.ci90[1], color=c, alpha=0.18, lw=0)
            ax.plot([lo, hi], [it.delta_mu] * 2, color=c, lw=1.5, label=plain(it.item))
            drawn = True
        if xs:
            ax.plot(xs, ys, "o", color=c, ms=4)
    if not drawn:
        return None
    ax.axhline(0.0, color="#555", lw=0.8)
    ax.set_xlabel("snow temperature (°C) of the day")
    ax.set_ylabel(f"Δμ against {plain(res.reference)}")
    ax.legend(fontsize=7, loc="best")
    return png(fig)


def network_figure(days: Sequence[Any], colours: dict[str, str]) -> str:
    """The items on a circle, a line between two for the days they met (thicker: more days)."""
    items = sorted({it for d in days for it in d.items})
    met: dict[tuple[str, str], int] = {}
    for d in days:
        for a in d.items:
            for b in d.items:
                if a < b:
                    met[(a, b)] = met.get((a, b), 0) + 1
    n = len(items)
    pos = {it: (math.cos(2 * math.pi * k / n), math.sin(2 * math.pi * k / n))
           for k, it in enumerate(items)}  # fmt: skip
    fig = figure(3.6)
    ax = fig.add_subplot()
    most = max(met.values(), default=1)
    for (a, b), k in met.items():
        (xa, ya), (xb, yb) = pos[a], pos[b]
        ax.plot([xa, xb], [ya, yb], color="#888", lw=0.8 + 4.0 * k / most, zorder=1)
        # the count 40 % of the way along its line, on a white patch: at the midpoint the
        # diagonals of four items all wrote theirs on the centre, over each other
        ax.text(xa + 0.4 * (xb - xa), ya + 0.4 * (yb - ya), str(k), fontsize=7, color="#444",
                ha="center", va="center", zorder=3,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none"})  # fmt: skip
    for it, (x, y) in pos.items():
        ax.scatter([x], [y], s=120, color=colours.get(it, "#333"), zorder=2)
        # the name outside its node, leaning away from the circle (centred, a long name on the
        # left or right of the circle was written over its node)
        ha = "left" if x > 0.3 else "right" if x < -0.3 else "center"
        va = "bottom" if y > 0.3 else "top" if y < -0.3 else "center"
        ax.text(x * 1.1, y * 1.1, plain(it), fontsize=8, ha=ha, va=va)
    ax.set_xlim(-2.2, 2.2)
    ax.set_ylim(-1.45, 1.45)
    ax.set_aspect("equal")
    ax.axis("off")
    return png(fig)


def season_verdicts(res: Any, by: str) -> str:
    """The answer first, in words and numbers, as the day report gives it: per item against
    the reference, which glides better across the days, Δμ with its 90 % interval (the
    between-day heterogeneity in it), how sure, on how many days and descents, and whether
    the interval settles it. An item that cannot be compared says why."""
    ref = esc(res.reference)
    where = ", ".join(f"{esc(k)} = {v:g}" for k, v in res.at.items())
    lines = []
    for it in sorted(res.items, key=lambda i: (i.delta_mu is None, i.delta_mu or 0.0)):
        if it.item == res.reference:
            continue
        name = esc(it.item)
        if it.delta_mu is None or it.ci90 is None or it.p_faster is None:
            why = esc(it.note) if it.note else "no interval"
            lines.append(("none", f"<b>{name}</b> against <b>{ref}</b>: not comparable ({why})"))
            continue
        lo, hi = it.ci90
        item_better = it.delta_mu < 0
        better, worse = (name, ref) if item_better else (ref, name)
        size, blo, bhi = (-it.delta_mu, -hi, -lo) if item_better else (it.delta_mu, lo, hi)
        p = it.p_faster if item_better else 1.0 - it.p_faster
        sure = "> 0.999" if p > 0.999 else f"{p:.3f}"
        numbers = (
            f"by Δμ {size:.5f} [{blo:+.5f}, {bhi:+.5f}] (90 %); P({better} faster) {sure}; "
            f"{it.days} days, {it.descents} descents"
        )
        if lo > 0 or hi < 0:
            head = f"<b>{better}</b> glides better than <b>{worse}</b>"
            tail = "<b>decided</b>: the 90 % interval excludes 0"
            kind = "decided"
        else:
            head = f"<b>{better}</b> ahead of <b>{worse}</b>"
            tail = "<b>not decided</b>: the 90 % interval includes 0"
            kind = "open"
        lines.append((kind, f"{head} <span class='numbers'>{numbers}</span>. {tail}."))
    if not lines:
        lines.append(("none", f"one {esc(by)} only: nothing to compare"))
    items = "".join(f"<li class='{k}'>{h}</li>" for k, h in lines)
    at = f" at {where}" if where else ""
    return (
        f"<ul class='verdicts'>{items}</ul><p class='sub'>Each {esc(by)} against {ref}{at}, "
        f"across {res.days} days (between-day heterogeneity τ = {res.tau:.5f} in every "
        "interval).</p>"
    )


def build_season_report(
    res: Any, days: Sequence[Any], conditions: Mapping[str, Mapping[str, Any]], by: str
) -> str:

    ranked = sorted(res.items, key=lambda i: (i.delta_mu is None, i.delta_mu or 0.0))
    colours = item_colours([i.item for i in ranked])
    at = ", ".join(f"{k} = {v:g}" for k, v in res.at.items())
    rows = [
        [str(k), it.item, str(it.days), str(it.descents),
         "reference" if it.item == res.reference else num(it.delta_mu, "+.5f"),
         f"[{it.ci90[0]:+.5f}, {it.ci90[1]:+.5f}]"
         if it.ci90 and it.item != res.reference else "—",
         num(it.p_faster, ".3f"), num(it.p_best, ".3f"), it.note]
        for k, it in enumerate(ranked, start=1)
    ]  # fmt: skip
    warn = "".join(f"<p class='warn'>{esc(w)}</p>" for w in res.warnings)
    sections = [
        Section("verdict", "Verdict", season_verdicts(res, by)),
        Section(
            "ranking",
            "Ranking" + (f" at {at}" if at else ""),
            f"<p>Δμ of each {esc(by)} against {esc(res.reference)} (negative: glides better), "
            "from the within-day differences of every day, joined through the items the days "
            f"shared. Between-day heterogeneity τ = {res.tau:.5f} is in every interval.</p>",
            after=table(
                ["rank", by, "days", "descents", "Δμ", "90 % CI", "P(faster)", "P(best)", "note"],
                rows,
            )
            + warn,  # fmt: skip
        ),
    ]
    fig = effects_figure(res, days, colours)
    if fig:
        sections.append(Section(
            "temperature", "Δμ against snow temperature",
            "<p>Points: the difference on each day the item met the reference; band: the "
            "season's estimate and its 90 % interval over the temperatures it was tested at.</p>",
            fig, "Δμ of each item against the reference over snow temperature"))  # fmt: skip
    sections.append(Section(
        "network", "Which items met on which day",
        "<p>A line joins two items for the days they were tested on together (the number: "
        "how many days). Items are compared only through such lines.</p>",
        network_figure(days, colours), "the network of items and days"))  # fmt: skip
    day_rows = []
    for d in days:
        c = conditions.get(d.day, {})
        day_rows.append([d.day, num(c.get("snow_temperature_c"), ".1f"),
                         num(c.get("air_temperature_c"), ".1f"), c.get("snow_type") or "—",
                         c.get("wetness") or "—", c.get("hardness") or "—",
                         num(c.get("grain_size_mm"), ".2g"), "; ".join(d.items),
                         str(sum(d.descents))])  # fmt: skip
    sections.append(Section(
        "days", "The days", "",
        after=table(["session", "snow °C", "air °C", "snow type", "wetness", "hardness",
                      "grain mm", "items", "descents"], day_rows)))  # fmt: skip
    return render_html(
        "Season comparison",
        f"{res.counts()}, by {by}, against {res.reference}",
        sections,
    )


def write_season_report(
    folder: str, res: Any, days: Sequence[Any], conditions: Mapping[str, Any], by: str
) -> str:
    path = os.path.join(folder, REPORT)
    page = build_season_report(res, days, conditions, by)
    write_atomic(path, [page.encode("utf-8")])
    return path
