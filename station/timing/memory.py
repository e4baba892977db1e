"""The timer's memory joined to the live recording: a download (TAG ``DS`` … ``DE``, ALGE
``m`` lines, ``station import``) may continue a descent the live line lost (the cable came
out), and a descent from the memory may take the live rest no descent took."""

from __future__ import annotations

from station.timing.assembler_base import AssemblerBase
from station.timing.descent import (
    JOINED,
    REOPENED,
    ImpulseEvent,
    TimedDescent,
    is_joined,
    live_then_memory,
)

#: live impulses no descent took, remembered for a descent from the memory to take
MAX_ORPHANS = 200


class MemoryJoins(AssemblerBase):
    """Descents reopened, continued or completed across the live line and the memory."""

    def _memory_join(
        self, chosen: TimedDescent | None, pc: str, k: int, t: int, bib: str
    ) -> tuple[TimedDescent | None, str]:
        """An impulse from the timer's memory at photocell ``pc`` (index ``k``): the descent
        that takes it (``chosen``, the open one pairing chose, or else one that ended short
        and it continues, reopened) and the flag that says it was joined ("" if none)."""
        if chosen is None:
            chosen = self._rejoin(pc, k, t, bib)
            return chosen, chosen.flags[-1] if chosen is not None else ""
        return chosen, self._continued(chosen, pc)

    def _rejoin(self, pc: str, k: int, t: int, bib: str) -> TimedDescent | None:
        """A descent that ended short of photocell ``k`` (timed out, the timer disconnected,
        the recording ended) and that an impulse from the timer's memory continues plausibly:
        open again to take it and the rest, its crossing times all the timer's own. Of those
        that can, the one the order pairing would choose (:meth:`_score`: nearest the time
        it was expected there); None: none can. (The one whose last crossing was latest took
        the crossing of the skier ahead when two were cut short at one photocell.)"""
        best: tuple[tuple[float, int], TimedDescent] | None = None
        reach = max(self.timeout_us)
        for d in self._short:
            if not d.times_us or not d.times_us[-1] < t <= d.times_us[-1] + reach:
                continue
            if d.status not in ("incomplete", "aborted") or self.order[d.photocells[-1]] >= k:
                continue  # (changed by an edit since)
            if self.mode != "order" and bib and d.bib and d.bib != bib:
                continue
            if self._why_not(d, pc, k, t, by_order=True) is not None:
                continue
            score = self._score(d, k, t)
            if best is None or score < best[0]:
                best = (score, d)
        if best is None:
            return None
        d = best[1]
        d.thaw()
        last = d.photocells[-1]
        tail = self.photocells[self.order[last] + 1 :]
        ended = f"; missing {', '.join(tail)}"
        for i in range(len(d.flags) - 1, -1, -1):  # how it ended no longer holds
            f = d.flags[i]
            if f.endswith(ended) or (len(d.photocells) == 1 and f.startswith("lone ")):
                del d.flags[i]
                break
        d.missing = [p for p in d.missing if p not in tail]
        if d.number in self._memory_starts and not is_joined(d):
            # begun in the memory and nothing live taken since: a tick while the download
            # came (a pause on the line, by the memory's clock) ended it, and the memory goes
            # on with it. It said "recorded live" here: the import listed it as joined
            d.flags.append(
                f"{REOPENED}{pc} on from the timer's memory, as were {last} and "
                "those before (a time-out while the download came had ended it)"
            )
        else:
            d.flags.append(live_then_memory(last, pc))
        d.status = "open"
        self.finished.remove(d)
        self._short.remove(d)
        if self._last_done is d:
            self._last_done = None
        self.open.append(d)
        return d

    def _continued(self, d: TimedDescent, pc: str) -> str:
        """An impulse from the timer's memory at ``pc`` that open descent ``d`` takes: when
        ``d``'s crossings so far were recorded live (the cable came out during it, and the
        download came before its time-out ended it), the flag that says it was joined, added
        to ``d``; "" otherwise (a descent from the memory, or one that says so already).
        Without it a descent the download continued in time said only "timer disconnected",
        while one it reopened (:meth:`_rejoin`) said it was joined."""
        if d.number in self._memory_starts or is_joined(d):
            return ""
        d.thaw()
        flag = live_then_memory(d.photocells[-1], pc)
        d.flags.append(flag)
        return flag

    def _adopt(self, d: TimedDescent) -> bool:
        """A descent from the timer's memory ending short: the live impulses no descent took
        that continue it plausibly (the cable came back in during it), taken into it, with a
        flag. True when it then reaches the last photocell. An impulse of another bib is not
        taken when bibs pair (it was: a skier who fell took the live rest of the one behind)."""
        last = d.photocells[-1] if d.photocells else None
        by_bib = self.mode != "order"
        taken = []
        for o in sorted(self._orphans, key=lambda o: o[2]):
            pc, k, t, ch, bib, line, tod, flag = o
            if by_bib and bib and d.bib and bib != d.bib:
                continue
            if not d.photocells or self._why_not(d, pc, k, t, by_order=True) is not None:
                continue
            if self._rival(d, pc, k, t, bib if by_bib else ""):
                continue  # an open descent would reach it when expected: its skier's
            self._join(d, pc, k, t, ch)
            taken.append(o)
            # its event said "without a start": a second one says where it went (--events)
            self.events.append(ImpulseEvent(line, ch, pc, tod, flag, True, f"{JOINED}taken by "
                                            f"descent {d.number}, begun in the timer's memory",
                                            d.number))  # fmt: skip
        if not taken:
            return False
        for o in taken:
            self._orphans.remove(o)
        d.flags.append(f"{JOINED}{last} from the timer's memory, {taken[0][0]} on recorded live")
        return d.photocells[-1] == self.photocells[-1]

    def _rival(self, d: TimedDescent, pc: str, k: int, t: int, bib: str) -> bool:
        """Another open descent (of the bib ``bib``, when given) can take photocell ``k`` at
        ``t`` and is nearer the time expected there than ``d`` (:meth:`_score`): the live
        rest of a skier whose start was in the timer's memory too, when ``d``'s skier fell."""
        mine = self._score(d, k, t)
        for e in self.open:
            if e is d or not e.photocells or (bib and e.bib and e.bib != bib):
                continue
            if self._why_not(e, pc, k, t, by_order=True) is None and self._score(e, k, t) < mine:
                return True
        return False
