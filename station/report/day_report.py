"""The day report: one self-contained HTML page (:mod:`station.report.page`) with the pictures
of a test day (:mod:`station.report.day_figures`), for the coach and the ski maker who were not
at the trackside: the answer first (a verdict per comparison), μ and CdA over the day, the
comparison of the items, the track, every descent's residuals and speed, then the session's
metadata and provenance (station version, config and survey with their digests, what the
timer sent, every descent in a table, and the warnings)."""

from __future__ import annotations

import datetime as dt
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from station import __version__
from station.model.estimate import Estimate
from station.report.day_data import DayData, DescentView
from station.report.day_figures import (
    comparison_figure,
    count_valid,
    descents_figure,
    drift_reference_hours,
    hhmm,
    item_colours,
    profile_figure,
    time_of_day_figure,
)
from station.report.page import Section, esc, num, render_html, table

if TYPE_CHECKING:
    from station.session.comparison import DayComparison


# ----------------------------------------------------------------------------- pictures


# ----------------------------------------------------------------------------- page


def _descent_rows(descents: Sequence[DescentView]) -> list[list[str]]:
    def rng(est: Estimate, spec: str) -> str:
        v, c = est.value, est.ci90
        if v is None:
            return "—"
        return f"{format(v, spec)} [{format(c[0], spec)}, {format(c[1], spec)}]" if c else (
            format(v, spec))  # fmt: skip

    return [
        [str(d.number), d.start_time.replace("T", " ")[:19], d.item, rng(d.mu, ".5f"),
         rng(d.cda, ".4f"), num(d.v0.value, ".2f"), num(d.rms_ms, ".2f"),
         str(d.photocells_used), d.status,
         "; ".join(x for x in (d.invalid_reason and f"invalid: {d.invalid_reason}", d.notes,
                               d.flags) if x)]
        for d in descents
    ]  # fmt: skip


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
            f"<p>{esc(track.name)}: {len(track.photocells)} photocells over "
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
                    f"the reference {esc(ref)}: {count_valid(by[ref])}"
                )
            out.append(Verdict("none", f"<b>{esc(name)}</b> against <b>{esc(ref)}</b>: "
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
            f"run at v0 {res.typical_v0:.1f} m/s; P({esc(better)} faster) {sure}; "
            f"{len(it.descents)} descents of {esc(name)}, {n_ref} of {esc(ref)}"
        )
        decision = day.decision(cmp)
        assert decision is not None
        if decision.state == "decided":
            head = f"<b>{esc(better)}</b> glides better than <b>{esc(worse)}</b>"
            r_lo, r_hi = sorted(abs(x) for x in decision.interval or (lo, hi))
            tail = (f"<b>decided</b>: the interval widened for a look after every "
                    f"descent, [{r_lo:+.5f}, {r_hi:+.5f}], excludes 0, as station compare "
                    "decides")  # fmt: skip
            kind = "decided"
        else:
            head = f"<b>{esc(better)}</b> ahead of <b>{esc(worse)}</b>"
            why = decision_words(decision).removeprefix("not yet: ")
            if not decision.reason and (lo > 0 or hi < 0):
                why = f"the 90 % interval excludes 0 but not yet at this look's boundary; {why}"
            tail = f"<b>not decided</b>: {esc(why)}"
            kind = "open"
        out.append(Verdict(kind, f"{head} <span class='numbers'>{numbers}</span>. {tail}."))
    if len(res.items) == 1:
        it = res.items[0]
        out.append(Verdict("none", f"one item only (<b>{esc(it.item)}</b>, "
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
            f"{hhmm(t_ref)} (timer's time of day), the mean start time of the "
            f"{len(day.compared)} compared descents")  # fmt: skip


def _verdict_section(day: DayData) -> Section:
    """The answer, first on the page."""
    res = day.comparison
    if res is None:
        return Section("verdict", "Verdict",
                       f"<p class='err'>No comparison: {esc(day.comparison_error or 'no data')}"
                       ".</p>")  # fmt: skip
    assert day.day_comparison is not None
    lines = verdicts(day.day_comparison)
    items = "".join(f"<li class='{v.kind}'>{v.html}</li>" for v in lines)
    intro = f"<ul class='verdicts'>{items}</ul>"
    notes = []
    if res.status != "ok":
        notes.append(f"<p class='err'>Joint fit {esc(res.status)}: {esc(res.message)}</p>")
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        t_ref = drift_reference_hours(day.compared)
        when = ""
        if t_ref is not None:
            when = f" (μ of each item at {hhmm(t_ref)}, the compared descents' mean start)"
        apart = "" if res.drift_separable else " — <b>not separable from the items</b>"
        notes.append(
            f"<p>Drift of μ over the day {d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]"
            f"{esc(when)}{apart}.</p>"
        )
    left_out = len(res.excluded)
    notes.append(f"<p class='sub'>Joint fit of {len(day.compared)} valid descents"
                 + (f"; {left_out} left out (see the comparison)" if left_out else "")
                 + f"; reference {esc(res.reference)}.</p>")  # fmt: skip
    return Section("verdict", "Verdict", intro + "".join(notes))


def _comparison_section(day: DayData, colours: dict[str, str], format_comparison) -> Section:
    res = day.comparison
    if res is None:
        return Section(
            "comparison",
            "Comparison of the items",
            f"<p class='err'>No comparison: {esc(day.comparison_error or 'no data')}.</p>",
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
            + (f", μ of each item at {hhmm(t_ref)}" if t_ref is not None else "")
            + ("" if res.drift_separable else " — NOT separable from the items")
        )
    cda = "; ".join(f"{esc(g)} {e.value:.4f} m²" + (f" [{e.lo:.4f}, {e.hi:.4f}]" if e.ci90 else
                    " (fixed)") for g, e in res.cda.items())  # fmt: skip
    notes = "".join(f"<p class='warn'>{esc(w)}</p>" for w in res.warnings)
    left_out = "".join(f"<li>descent {n}: {esc(why)}</li>" for n, why in res.excluded)
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
        f"status {esc(res.status)}.</p><p>Drift of μ: {esc(drift)}. CdA: {cda}. Posture scatter "
        f"(CdA between descents of a skier): {esc(posture)}.</p>{notes}"
    )
    mu_head = f"μ at {hhmm(t_ref)}" if res.drift_per_hour and t_ref is not None else "μ"
    after = table(["rank", "item", "descents", mu_head, "90 % interval",
                    f"Δμ vs {res.reference}", "P(faster than reference)",
                    "Δt over the run [ms]"], rows)  # fmt: skip
    if left_out:
        after += f"<p>Left out of the comparison:</p><ul>{left_out}</ul>"
    after += f"<details><summary>as the terminal shows it</summary><pre>" \
             f"{esc(format_comparison(res, len(day.compared)))}</pre></details>"  # fmt: skip
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
    warn = "".join(f"<p class='warn'>{esc(w)}</p>" for w in day.warnings)
    after = table(None, meta, "meta")
    after += "<h3>Descents</h3>" + table(
        ["#", "start", "item", "μ [90 %]", "CdA [m²] [90 %]", "v0 [m/s]", "rms [ms]",
         "photocells", "status", "notes"], _descent_rows(day.descents))  # fmt: skip
    if day.config_text:
        after += f"<details><summary>config.yaml of the session</summary><pre>" \
                 f"{esc(day.config_text)}</pre></details>"  # fmt: skip
    return Section("provenance", "Session metadata and provenance", warn, None, "", after)
