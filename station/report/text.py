"""Text for the terminal: one line per descent, and the summary of a recording or replay.

Shared by ``station record``, ``station replay`` and the UI, so a descent reads the same
wherever it is shown.
"""

from __future__ import annotations

from collections.abc import Sequence

from station.model.estimate import Estimate
from station.session.analysis import DescentResult
from station.session.records import LineCounts


def num(v: float | None, spec: str) -> str:
    """A number, or — where there is none (or it is NaN)."""
    return "—" if v is None or v != v else format(v, spec)


def count(n: int, word: str) -> str:
    """``1 descent``, ``2 descents``: a line people read says it as they would."""
    return f"{n} {word}{'s' * (n != 1)}"


def local_time(iso: str) -> str:
    """A start time for people at the trackside: date and local time to 1/100 s, without the
    UTC offset the results CSV carries (``2026-02-02T10:41:07.234500+01:00`` ->
    ``2026-02-02 10:41:07.23``)."""
    text = iso.replace("T", " ")
    if len(text) > 6 and text[-6] in "+-" and text[-3] == ":":
        text = text[:-6]
    return text[:22]


def describe(res: DescentResult) -> str:
    """One line per descent, for the terminal."""
    d, f, row = res.descent, res.fit, res.row
    when = local_time(res.start_time)
    used = f"{len(d.photocells)}/{len(d.photocells) + len(d.missing)}"
    head = f"descent {d.number:>3}  {when}  {used} photocells"
    mark = f"  INVALID: {row.invalid_reason or 'marked invalid'}" if row.invalid else ""
    if f is None:
        return f"{head}  {row.status}: {'; '.join(row.flags)}{mark}"

    def part(name: str, est: Estimate, spec: str) -> str:
        if est.value is None:
            return f"{name} —"
        c = est.ci90
        rng = f" [{format(c[0], spec)}, {format(c[1], spec)}]" if c else ""
        return f"{name} {format(est.value, spec)}{rng}"

    text = (
        f"{head}  {part('μ', f.mu, '.5f')}  {part('CdA', f.cda, '.4f')}  "
        f"v0 {num(f.v0.value, '.2f')}  rms {num(row.rms_residual_ms, '.2f')} ms  {row.status}"
    )
    if row.flags:
        text += f"  ({'; '.join(row.flags)})"
    return text + mark


def impulses_text(counts: LineCounts) -> str:
    """``N impulses`` and how many of them came from the timer's memory: an import's memory
    lines (ALGE ``m``) are impulses, and were counted as edits."""
    memory = f" ({counts.from_memory} from the timer's memory)" if counts.from_memory else ""
    return count(counts.impulses, "impulse") + memory


def summary(counts: LineCounts, results: Sequence[DescentResult]) -> str:
    """Lines by kind, descents by status."""
    st: dict[str, int] = {}
    for r in results:
        st[r.row.status.value] = st.get(r.row.status.value, 0) + 1
    parts = ", ".join(f"{v} {k}" for k, v in sorted(st.items()))
    invalid = sum(1 for r in results if r.row.invalid)
    return (
        f"{count(counts.lines, 'line')}: {impulses_text(counts)}, "
        f"{count(counts.edits, 'edit')}, {count(counts.skipped, 'other timer line')}, "
        f"{counts.unparsed} unparsed; "
        f"{count(len(results), 'descent')}"
        + (f" ({parts})" if parts else "")
        + (f", {invalid} marked invalid" if invalid else "")
    )
