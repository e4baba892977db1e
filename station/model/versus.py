"""One sign convention for the day's comparisons: an item against the reference, item minus
reference (negative Δμ: the item glides better), for every table and picture that lists
items against the reference."""

from __future__ import annotations

from dataclasses import dataclass

from station.model.compare_types import Comparison, JointResult


@dataclass(frozen=True)
class Versus:
    """Item ``item`` against the reference: Δμ = μ_item − μ_reference with its 90 % interval,
    P(item faster), and the time the item takes minus the reference's over the run."""

    item: str
    reference: str
    delta_mu: float
    ci90: tuple[float, float]
    p_faster: float
    delta_t_s: float
    #: the joint fit's own comparison (reference minus item), for what is not re-signed
    comparison: Comparison


def versus(res: JointResult, item: str) -> Versus | None:
    """``item`` against ``res``'s reference; None for the reference itself and for an item
    with no interval against it."""
    ref = res.reference
    if ref is None or item == ref:
        return None
    c = next((c for c in res.comparisons if c.a == ref and c.b == item), None)
    if c is None or c.ci90 is None or c.p_a_faster is None:
        return None
    return Versus(item, ref, -c.delta_mu, (-c.ci90[1], -c.ci90[0]), 1 - c.p_a_faster,
                  -c.delta_t_s, c)  # fmt: skip
