"""The day's comparison in words: the block the terminal, the UI and the report show, the
decision on each pair, and the phrases of it the report reuses (the posture scatter, the χ² p).
Rendering of the one typed :class:`~station.session.comparison.DayComparison` that every view
is given (``station compare``'s text, JSON and ranking CSV, the UI's panel, ``station
record``'s console); the model itself says nothing in prose but its warnings."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from typing import IO, Any

from station import __version__, csvfiles
from station.model.compare_types import ComparisonStatus, JointResult
from station.model.sequential import MAX_MORE, Decision
from station.model.versus import versus
from station.report.text import count
from station.session.comparison import DayComparison


def chi2_p_words(p: float) -> str:
    """``p = 0.36``, or ``p > 0.99`` / ``p < 0.001`` at the ends: two significant figures
    round 0.996 up to "p = 1", which reads as a certainty no test gives."""
    if p > 0.99:
        return "p > 0.99"
    if p < 1e-3:
        return "p < 0.001"
    return f"p = {p:.2g}"


def posture_words(res: JointResult) -> str:
    """The posture scatter as the text, the report and the UI say it: "1.08 % [0.69, 1.68] %",
    or "0.00 % (none seen beyond the timing noise)" when no interval and below 0.1 %."""
    words = f"{res.posture_sd * 100:.2f} %"
    if res.posture_ci90:
        return words + f" [{res.posture_ci90[0] * 100:.2f}, {res.posture_ci90[1] * 100:.2f}] %"
    if res.posture_sd < 1e-3:
        return words + " (none seen beyond the timing noise)"
    return words


def format_comparison(res: JointResult, n_desc: int) -> str:
    """The comparison as the terminal shows it (CLI and UI)."""
    verdict = {
        ComparisonStatus.OK: "ok",
        ComparisonStatus.POOR_FIT: "POOR FIT",
        ComparisonStatus.NOT_CONVERGED: "NOT CONVERGED",
    }
    lines = [
        f"joint fit of {count(n_desc, 'descent')}, {count(len(res.items), 'item')}, "
        f"{res.dof} dof, timing "
        f"residual {res.sigma_s * 1000:.2f} ms against a timer of {res.timer_sd_s * 1000:.2f} ms"
        + (f" (χ² {chi2_p_words(res.chi2_p)})" if res.chi2_p is not None else "")
        + f": {verdict[res.status]}"
    ]
    if res.message:
        lines.append(f"  {res.message}")
    for g, est in res.cda.items():
        c = est.ci90
        rng = f"[{c[0]:.4f}, {c[1]:.4f}]" if c else "(fixed)"
        lines.append(f"  CdA {g}: {est.value:.4f} m² {rng} (mean over the skier's descents)")
    lines.append(f"  posture scatter (CdA between descents of a skier): {posture_words(res)}")
    if res.drift_per_hour:
        d, (lo, hi) = res.drift_per_hour
        sep = "" if res.drift_separable else "  NOT SEPARABLE FROM ITEM"
        lines.append(f"  drift of μ: {d:+.5f} per hour [{lo:+.5f}, {hi:+.5f}]{sep}")
        if res.drift_bend:
            b, (blo, bhi) = res.drift_bend
            lines.append(f"  bending by {b:+.5f} per hour² [{blo:+.5f}, {bhi:+.5f}]")
    lines.append("")
    # the item column as wide as the names (at most the 28 of long names): the table fits an
    # 80-column terminal and the UI's comparison dialog with the names people use
    w = min(28, max([6, *(len(i.item) + 2 for i in res.items)]))
    lines.append(f"{'rank':<5}{'item':<{w}}{'descents':>9}{'μ':>10}   90 % CI{'':<14}P(best)")
    for k, name in enumerate(res.ranking, start=1):
        it = res.item(name)
        pb = f"{it.p_best:.3f}" if it.p_best is not None else "—"
        ci = f"[{it.ci90[0]:.5f}, {it.ci90[1]:.5f}]"
        lines.append(f"{k:<5}{it.item:<{w}}{len(it.descents):>9}{it.mu:>10.5f}   {ci:<21}{pb}")
        if it.mu1 is not None and it.mu1_ci90 is not None:
            flag = "  (not distinguishable from 0)" if it.mu1_ci90[0] <= 0 <= it.mu1_ci90[1] else ""
            lines.append(f"{'':<5}  μ1 {it.mu1:.2e} s/m [{it.mu1_ci90[0]:.2e}, "
                         f"{it.mu1_ci90[1]:.2e}]{flag}")  # fmt: skip
    lines.append("")
    for c in res.comparisons:
        if c.ci90 is None or c.p_a_faster is None:
            lines.append(f"{c.a} − {c.b}: {c.note}")
            continue
        lines.append(
            f"{c.a} − {c.b}: Δμ {c.delta_mu:+.5f} [{c.ci90[0]:+.5f}, {c.ci90[1]:+.5f}], "
            f"P({c.a} faster) = {c.p_a_faster:.3f}, "
            f"{c.delta_t_s * 1000:+.1f} ms over the run at v0 {res.typical_v0:.1f} m/s"
        )
    for n, why in res.excluded:
        lines.append(f"  descent {n} left out: {why}")
    return "\n".join(lines)


#: the first words of the decision block
BLOCK_HEADER = "decided or not after descent"


def decision_words(d: Decision) -> str:
    """ "decided: A faster by Δμ 0.00100 [0.00042, 0.00158]", "equivalent: …" or
    "not yet: about k more descents per item at today's scatter"."""
    if d.state == "decided" and d.interval is not None:
        lo, hi = sorted(abs(v) for v in d.interval)
        return f"decided: {d.faster} faster by Δμ {abs(d.delta_mu):.5f} [{lo:.5f}, {hi:.5f}]"
    if d.state == "equivalent" and d.interval is not None and d.margin is not None:
        lo, hi = d.interval
        ahead = f" ({d.faster} faster, by less than that)" if d.faster else ""
        return (f"equivalent: Δμ {d.delta_mu:+.5f} [{lo:+.5f}, {hi:+.5f}] lies within "
                f"±{d.margin:g}: no difference that matters{ahead}")  # fmt: skip
    if d.reason:
        return f"not yet: {d.reason}"
    if d.interval is None:
        return "not yet: a comparison needs two descents of each item"
    if d.more_descents_per_item is None:
        return (f"not yet: no difference in sight (more than {MAX_MORE} more descents per item "
                "at today's scatter)")  # fmt: skip
    k = d.more_descents_per_item
    return f"not yet: about {k} more descent{'s' * (k != 1)} per item at today's scatter"


def decision_lines(decisions: Sequence[Decision]) -> list[str]:
    """One line per pair: "A vs B: decided: A faster by Δμ … [..]" or "… not yet: …"."""
    return [f"{d.a} vs {d.b}: {decision_words(d)}" for d in decisions]


def decision_block(day: DayComparison) -> list[str]:
    """The decision on every pair: a header line and one indented line per pair (no lines
    when there is no pair)."""
    if not day.decisions:
        return []
    head = (f"{BLOCK_HEADER} {day.last_descent}, with a look after every descent "
            f"(α spent over {day.horizon} descents per item):")  # fmt: skip
    return [head, *(f"  {line}" for line in decision_lines(day.decisions))]


def comparison_view(day: DayComparison) -> str:
    """The UI's comparison panel: the decisions first, each pair's on a line of its own with
    its decision below it (no phrase broken at 80 columns), then the joint fit of the day's
    valid descents and its warnings (a line for why there is none yet)."""
    res = day.result
    if res is None:
        return f"no comparison yet: {day.error}"
    text = format_comparison(res, len(day.numbers)) + "".join(f"\n! {w}" for w in res.warnings)
    block = decision_block(day)
    if not block:
        return text
    head = block[0].replace(", with a look", ",\nwith a look", 1)
    pairs = [f"  {d.a} vs {d.b}:\n      {decision_words(d)}" for d in day.decisions]
    return "\n".join([head, *pairs, "", text])


def _leading_pair(day: DayComparison) -> Decision | None:
    """The decision between the leader and the runner-up (else the first of the leader's)."""
    res = day.result
    if res is None or not day.decisions:
        return None
    top = set(res.ranking[:2])
    for d in day.decisions:
        if {d.a, d.b} == top:
            return d
    lead = res.ranking[0]
    return next((d for d in day.decisions if lead in (d.a, d.b)), day.decisions[0])


def headline(day: DayComparison | None) -> str:
    """One line for the UI's main screen: which item leads, by how much, and decided or not,
    in the decisions' own words ("A vs B: decided: A faster by Δμ …")."""
    if day is None:
        return "comparison: none yet (enter ski or wax with m)"
    d = _leading_pair(day)
    if d is None:
        why = day.error or "one item only: enter ski or wax with m"
        return f"comparison: none yet ({why})"
    res = day.result
    assert res is not None
    lead = res.ranking[0]
    other = d.b if lead == d.a else d.a
    ahead = "" if d.state == "decided" else f"{lead} ahead by Δμ {abs(d.delta_mu):.5f} · "
    more = len(day.decisions) - 1
    rest = f" · {more} more pair{'s' * (more != 1)} (c)" if more else ""
    return f"{ahead}{decision_words(d)} · {lead} vs {other}{rest}"


def compare_text(day: DayComparison) -> str:
    """What ``station compare`` prints: the joint fit, then the decisions (its warnings go to
    standard error)."""
    assert day.result is not None
    block = decision_block(day)
    text = format_comparison(day.result, len(day.numbers))
    return text + ("\n\n" + "\n".join(block) if block else "")


def comparison_json(day: DayComparison) -> dict[str, Any]:
    """``station compare --json``: the joint fit's fields, each comparison with its decision."""
    assert day.result is not None
    out = day.result.to_dict()
    for c, d in zip(out["comparisons"], day.decisions, strict=True):
        c["decision"] = d.to_dict()
    return out


def write_ranking_csv(day: DayComparison, fh: IO[str]) -> None:
    """``station compare --csv``: the ranking, each item against the reference (item minus
    reference). An item name is the user's text: one header line whatever it holds, and a
    name that looks like a formula is shown as text (:mod:`station.csvfiles`)."""
    res = day.result
    assert res is not None
    head = [f"station {__version__} comparison", f"reference {res.reference}",
            f"drift {'on' if res.drift_per_hour else 'off'}",
            f"g {res.gravity_ms2:.5f} m/s²"]  # fmt: skip
    fh.write("# " + "; ".join(csvfiles.header_text(h) for h in head) + "\n")
    w = csvfiles.writer(fh, quoting=csv.QUOTE_NONNUMERIC)
    w.writerow(["rank", "item", "descents", "mu", "mu_lo", "mu_hi", "delta_mu_vs_reference",
                "delta_lo", "delta_hi", "p_faster_than_reference", "delta_t_s"])  # fmt: skip
    for k, name in enumerate(res.ranking, start=1):
        it = res.item(name)
        v = versus(res, name)
        row = [None] * 5 if v is None else [v.delta_mu, *v.ci90, v.p_faster, v.delta_t_s]
        w.writerow([k, it.item, len(it.descents), it.mu, it.ci90[0], it.ci90[1], *row])
