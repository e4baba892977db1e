"""The day's comparison in words: the block the terminal, the UI and the report show, and the
phrases of it the report reuses (the posture scatter, the χ² p). Rendering of
:class:`station.model.compare_types.JointResult`; the model itself says nothing in prose but its
warnings."""

from __future__ import annotations

from station.model.compare_types import ComparisonStatus, JointResult
from station.report.text import count


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
