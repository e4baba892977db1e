"""Recovery of a descent whose start line was damaged: an impulse at a later photocell that
no open descent can take starts a descent when a line the caller could not read came at a
time that skier's start could have been (see :mod:`station.timing.assembly`)."""

from __future__ import annotations

from station.timing.assembler_base import AssemblerBase, Damage
from station.timing.descent import TimedDescent
from station.timing.impulses import Impulse
from station.timing.pairing import SPEED_RATIO

#: damaged lines remembered for recovering a start (a flood of noise keeps the latest)
MAX_DAMAGED = 200


class Recovery(AssemblerBase):
    """The damaged lines remembered, and the start they may have been."""

    def note_damaged(self, line: int) -> None:
        """Line ``line`` could not be read (unparsed, a failed checksum, a corrupted time): it
        may have been a skier's start, so an impulse after it may start a descent without one."""
        self._damaged.append(Damage(line, self._clock))
        del self._damaged[:-MAX_DAMAGED]

    def _reach_us(self, k: int) -> tuple[int, int]:
        """(shortest, longest) plausible time from the first photocell to photocell k: from
        the survey's distance at the plausible speeds, narrowed to within a factor
        ``SPEED_RATIO`` of the earlier complete descents' typical time where there are some."""
        if self.positions is None:
            shortest, longest = 0, self.timeout_us[0] * k
        else:
            dist = self.positions[k] - self.positions[0]
            shortest = round(dist / self.max_speed * 1e6)
            longest = round(dist / self.min_speed * 1e6)
        mid = self._mid(k)
        if mid is not None:
            shortest = max(shortest, round(mid / SPEED_RATIO))
            longest = min(longest, round(mid * SPEED_RATIO))
        return shortest, longest

    def _damaged_start(self, line: int, k: int, t: int) -> Damage | None:
        """The latest damaged line before ``line`` that came when the start of a skier at
        photocell k at ``t`` could have been; None when there is none."""
        shortest, longest = self._reach_us(k)
        for dmg in reversed(self._damaged):
            before = t if dmg.before_us is None else dmg.before_us
            if (
                dmg.line < line
                and before >= t - longest
                and (dmg.after_us is None or dmg.after_us <= t - shortest)
            ):
                return dmg
        return None

    def _recover(
        self, imp: Impulse, line: int, pc: str, k: int, t: int, bib: str
    ) -> tuple[TimedDescent | None, str]:
        """A descent whose start line was damaged, started at photocell k (None when no
        damaged line came when this skier's start could have been), or why not."""
        if bib and self.mode != "order" and any(d.bib == bib for d in self.open):
            return None, ""
        dmg = self._damaged_start(line, k, t)
        if dmg is None:
            return None, ""
        if k == len(self.photocells) - 1:  # nothing can follow: one time is nothing to fit
            return None, f"line {dmg.line} before it was damaged (its start?); {pc} alone is " \
                "nothing to fit"  # fmt: skip
        self._damaged.remove(dmg)  # one damaged line starts one descent at most
        self.count += 1
        d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[imp.channel],
                         bib=bib if self.mode != "order" else "", day=imp.day,
                         missing=self.photocells[:k])  # fmt: skip
        d.flags.append(f"start line damaged (line {dmg.line}): the descent starts at {pc}")
        return d, ""
