"""The day's comparison in words: the decision on each pair and the comparison as the UI's
panel, ``station record``'s console and ``station compare`` print it, rendered from the one
typed :class:`~station.session.comparison.DayComparison` that every view is given."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from typing import IO, Any

from station import __version__, csvfiles
from station.model.compare import format_comparison
from station.model.sequential import MAX_MORE, Decision
from station.model.versus import versus
from station.session.comparison import DayComparison

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
    """The joint fit of the day's valid descents, its warnings and the decisions, as the UI
    shows it (a line for why there is none yet)."""
    res = day.result
    if res is None:
        return f"no comparison yet: {day.error}"
    text = format_comparison(res, len(day.compared)) + "".join(f"\n! {w}" for w in res.warnings)
    block = decision_block(day)
    return text + "".join(f"\n{line}" for line in ["", *block]) if block else text


def compare_text(day: DayComparison) -> str:
    """What ``station compare`` prints: the joint fit, then the decisions (its warnings go to
    standard error)."""
    assert day.result is not None
    block = decision_block(day)
    text = format_comparison(day.result, len(day.compared))
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
