"""Pairing: which open descent an impulse at a later photocell joins (by bib, or by the order
and the plausible speed), why none can take it, and the earlier descents' typical times
that the choice and the recovery of a damaged start read."""

from __future__ import annotations

from collections import deque

from station.timing.assembler_base import AssemblerBase
from station.timing.descent import TimedDescent, bib_of
from station.timing.impulses import Impulse

#: a speed between two photocells may be this factor off the speed before (order pairing)
SPEED_RATIO = 2.5


def _median(values: list[int]) -> float:
    """``statistics.median`` of a few ints, without its generality (one per photocell of every
    complete descent in a replay)."""
    s = sorted(values)
    m = len(s) // 2
    return s[m] if len(s) % 2 else (s[m - 1] + s[m]) / 2


class Pairing(AssemblerBase):
    """The pairing rules over :class:`AssemblerBase`'s open descents."""

    def _decide_mode(self, k: int, imp: Impulse, prev_number: int | None) -> str | None:
        """``auto`` decides at the first impulse after a start: the same number as an open
        descent's start means bibs, the previous impulse's number + 1 means a counter. The
        pairing then (None: still undecided)."""
        bib = bib_of(imp)
        if k > 0 and bib and self.open:
            if any(d.bib == bib for d in self.open):
                self.mode = "bib"
            elif prev_number is not None and int(bib) == (prev_number + 1) % 10000:
                self.mode = "order"  # an impulse counter, not a bib
                for d in self.open:
                    d.bib = ""
        return self.mode

    def _near(self, bib: str) -> int | None:
        """The descent an impulse was nearest to joining, for the events list."""
        for d in reversed(self.open):
            if not bib or d.bib == bib:
                return d.number
        return None

    def _why_not(self, d: TimedDescent, pc: str, k: int, t: int, by_order: bool) -> str | None:
        """Why descent ``d`` cannot take an impulse at photocell ``pc`` at ``t`` (None: it can)."""
        photocells, times = d.photocells, d.times_us  # (every impulse of a replay: at hand)
        order = self.order
        j = order[photocells[-1]]
        last = times[-1]
        if k < j:
            return f"out of order: {pc} after {photocells[-1]}"
        if k == j:
            return f"second impulse at {pc}, {(t - last) / 1e6:.3f} s after the first"
        if t <= last:
            return f"out of order: {(last - t) / 1e6:.4f} s earlier than {photocells[-1]}"
        if t - last > self.timeout_us[j]:
            return f"no impulse for {(t - last) / 1e6:.1f} s after {photocells[-1]}"
        pos = self.positions
        if pos is None:
            return None
        v = (pos[k] - pos[j]) / ((t - last) / 1e6)
        if v > self.max_speed:
            return (f"implausible: {v:.1f} m/s from {photocells[-1]} "
                    f"(at most {self.max_speed:g} m/s)")  # fmt: skip
        if by_order and len(photocells) >= 2:
            i = order[photocells[-2]]
            dt = (last - times[-2]) / 1e6
            if dt > 0:
                v_before = (pos[j] - pos[i]) / dt
                if not v_before / SPEED_RATIO <= v <= v_before * SPEED_RATIO:
                    return (f"implausible: {v:.1f} m/s from {photocells[-1]} after "
                            f"{v_before:.1f} m/s before it")  # fmt: skip
        return None

    def _expected(self, d: TimedDescent, k: int) -> tuple[int, int] | None:
        """(expected time at photocell k, from when) for the order pairing's choice: from the
        earlier descents' typical times where there are some, else at the last speed."""
        j = self.order[d.photocells[-1]]
        mid_k, mid_j = self._mid(k), self._mid(j)
        if mid_k is not None and (j == 0 or mid_j is not None):
            ahead = mid_k - (mid_j if j and mid_j is not None else 0)
            if ahead > 0:
                return d.times_us[-1] + round(ahead), d.times_us[-1]
        pos = self.positions
        if pos is not None and len(d.photocells) >= 2:
            i, j = self.order[d.photocells[-2]], self.order[d.photocells[-1]]
            dt = d.times_us[-1] - d.times_us[-2]
            if dt > 0 and pos[j] > pos[i]:
                v = (pos[j] - pos[i]) / dt
                return d.times_us[-1] + round((pos[k] - pos[j]) / v), d.times_us[-1]
        return None

    def _choose(self, pc: str, k: int, t: int, bib: str) -> tuple[TimedDescent | None, str]:
        """The open descent that takes photocell ``pc`` (index ``k``) at ``t``, or None and
        why none can: by bib where the number is one, else the one nearest its expected
        time of those that can reach it plausibly."""
        reasons: list[str] = []
        if self.mode != "order" and bib:
            pool = [d for d in self.open if d.bib == bib]
            if pool or self.mode == "bib":
                for d in pool:
                    why = self._why_not(d, pc, k, t, by_order=False)
                    if why is None:
                        return d, ""
                    reasons.append(why)
                return None, reasons[-1] if reasons else f"no open descent of bib {bib}"
        pool = self.open if self.mode == "order" else [d for d in self.open if not d.bib]
        if self.mode is None and bib:
            pool = self.open  # undecided: the number may be a counter
        scored: list[tuple[float, int, TimedDescent]] = []
        for d in pool:
            why = self._why_not(d, pc, k, t, by_order=True)
            if why is not None:
                reasons.append(why)
                continue
            exp = self._expected(d, k)
            # a photocell skipped is rare: a descent that would miss one to take this is less
            # likely than one that reaches it next (as :meth:`_score`, inline: the general
            # path's every impulse with several skiers on the run)
            skipped = 0.5 * (k - self.order[d.photocells[-1]] - 1)
            if exp is not None:
                score = abs(t - exp[0]) / max(exp[0] - exp[1], 1)
                scored.append((score + skipped, d.number, d))
            else:
                # no speed yet and no earlier descent to compare with: of two lone starts the
                # later one (a walk through the start beam comes before the real start)
                scored.append((0.75 + skipped, -d.number, d))
        if scored:
            return min(scored, key=lambda s: (s[0], s[1]))[2], ""
        if len(reasons) == 1:
            return None, reasons[0]
        if reasons:
            return None, f"no open descent can take {pc} plausibly ({'; '.join(reasons)})"
        return None, f"{pc} without a start at {self.photocells[0]}"

    def _score(self, d: TimedDescent, k: int, t: int) -> tuple[float, int]:
        """How well descent ``d`` taking photocell ``k`` at ``t`` fits (lower: better; then
        the tie-break): the order pairing's choice among descents that can take it, as
        :meth:`_choose` scores them."""
        exp = self._expected(d, k)
        # a photocell skipped is rare: a descent that would miss one to take this is less
        # likely than one that reaches it next
        skipped = 0.5 * (k - self.order[d.photocells[-1]] - 1)
        if exp is not None:
            return abs(t - exp[0]) / max(exp[0] - exp[1], 1) + skipped, d.number
        # no speed yet and no earlier descent to compare with: of two lone starts the later
        # one (a walk through the start beam comes before the real start)
        return 0.75 + skipped, -d.number

    def _record_typical(self, d: TimedDescent) -> None:
        """A complete descent's times from its start, into each photocell's history."""
        typical, order, stale = self._typical, self.order, self._stale
        times, photocells = d.times_us, d.photocells
        t0 = times[0]
        n = len(times)
        full = n == len(self.photocells)  # a time at every photocell: photocell i's at i
        for i in range(1, n):
            k = i if full else order[photocells[i]]
            hist = typical.get(k)
            if hist is None:
                hist = typical[k] = deque(maxlen=10)
            hist.append(times[i] - t0)
            stale.add(k)

    def _mid(self, k: int) -> float | None:
        """The median of the last complete descents' times to photocell k (None: none yet)."""
        if k in self._stale:
            self._stale.discard(k)
            self._typical_mid[k] = _median(list(self._typical[k]))
        return self._typical_mid.get(k)
