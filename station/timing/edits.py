"""Edits from the timer (ALGE ``c`` ``i``, TAG ``TC`` ``T+`` ``T*`` ``T-``): a cleared
impulse leaves its descent, an inserted or edited time enters or replaces one, and a finished
descent that changed comes out again to be refitted."""

from __future__ import annotations

from station.timing.assembler_base import AssemblerBase
from station.timing.descent import TimedDescent, bib_of
from station.timing.impulses import DAY_US, MEMORY_REPEAT, Edit, Impulse, format_tod

#: the kinds of edit that remove an impulse, enter one, or only repeat one
REMOVING = {"cleared", "memory time deleted", "disqualified", "cancelled",
            "identification removed"}  # fmt: skip
ENTERING = {"edited", "inserted"}


class Edits(AssemblerBase):
    """The timer's edits applied to the open and finished descents."""

    def _find(self, pc: str, tod_us: int, bib: str) -> tuple[TimedDescent, int] | None:
        """The kept impulse an edit names: photocell and time of day (and bib where given)."""
        for d in [*reversed(self.open), *reversed(self.finished)]:
            for i, (p, ti) in enumerate(zip(d.photocells, d.times_us, strict=True)):
                if p == pc and ti % DAY_US == tod_us and (not bib or not d.bib or d.bib == bib):
                    return d, i
        return None

    def edit(self, e: Edit, line: int = 0) -> list[TimedDescent]:
        """An edit from the timer; finished descents it changed come back to be refitted."""
        pc = self.channels.get(e.channel)
        if pc is None:
            self._event(
                e,
                line,
                None,
                False,
                f"{e.kind}: channel {e.channel} is not a photocell; nothing changed",
            )
            return []  # fmt: skip
        bib = bib_of(e) if self.mode != "order" else ""
        if e.kind == "new identification":
            done, removed = self._remove(e, line, pc, bib="")
            return done + (self._enter(e, line, pc, bib) if removed else [])
        if e.kind in REMOVING:
            return self._remove(e, line, pc, bib)[0]
        if e.kind in ENTERING:
            return self._enter(e, line, pc, bib)
        if e.kind == MEMORY_REPEAT:
            # ALGE `m`: an impulse from the timer's memory (a download): kept unless it is
            # already (a live impulse the memory repeats is not doubled)
            held: list[TimedDescent] = []
            if self._pending is not None and self._time(e.tod_us, e.day) < self._pending[2]:
                # a live impulse held for confirmation: the memory's earlier time neither
                # confirms nor refutes it (it called it corrupted: a live finish was lost)
                held = self._take_held()
            was, self.from_memory = self.from_memory, True
            try:
                return held + self.feed(
                    Impulse(e.channel, e.tod_us, 100, e.flag, e.bib, e.day, e.line), line
                )
            finally:
                self.from_memory = was
        self._event(e, line, pc, False, f"{e.kind}: repeats an earlier impulse; nothing changed")
        return []

    def _remove(self, e: Edit, line: int, pc: str, bib: str) -> tuple[list[TimedDescent], bool]:
        when = format_tod(e.tod_us)
        held = self._pending
        if (
            held is not None
            and held[0].channel == e.channel
            and held[0].tod_us == e.tod_us
            and (not bib or not bib_of(held[0]) or bib_of(held[0]) == bib)
        ):  # the impulse waits for the next one to confirm its time: it goes before it counts
            self._pending = None
            h_imp, h_line, _h_t = held
            self._event(h_imp, h_line, pc, False, f"{e.kind} at the timer (line {line}) while "
                        "waiting to be confirmed; joins nothing")  # fmt: skip
            self._event(e, line, pc, False, f"{e.kind}: removed {pc} {when}, which was waiting "
                        "to be confirmed; it joins nothing")  # fmt: skip
            return [], True
        found = self._find(pc, e.tod_us, bib)
        if found is None:
            self._event(
                e, line, pc, False, f"{e.kind}: no kept impulse at {pc} {when}; nothing changed"
            )
            return [], False  # fmt: skip
        d, i = found
        d.thaw()
        for lst in (d.photocells, d.times_us, d.channels):
            del lst[i]
        d.flags.append(f"{pc} {when} {e.kind} at the timer")
        is_open = d in self.open
        if not d.photocells:
            if is_open:
                self.open.remove(d)
                self.finished.append(d)
            d.status = "aborted"
            self._event(e, line, pc, False,
                        f"{e.kind}: removed {pc} {when}; descent {d.number} has no time left",
                        d.number)  # fmt: skip
            return [d], True
        if is_open:
            self._event(e, line, pc, False, f"{e.kind}: removed {pc} {when} from open descent "
                        f"{d.number}", d.number)  # fmt: skip
            return [], True
        if i == len(d.photocells) and d is self._last_done:
            # the finish was false (cleared at the timer) and the descent was the last to end:
            # it is open again, so the real finish joins it; it is fitted when it ends again
            self.finished.remove(d)
            d.status = "open"
            d.missing = [p for p in d.missing if self.order[p] < self.order[pc]]
            self.open.append(d)
            self._last_done = None
            why = f"{e.kind}: removed {pc} {when} from descent {d.number}, open again for its "
            self._event(e, line, pc, False, why + "next impulse", d.number)
            return [], True
        if i == len(d.photocells):  # the last time went: the descent no longer reaches there
            d.missing = [p for p in d.missing if self.order[p] < self.order[pc]]
            d.missing += self.photocells[self.order[d.photocells[-1]] + 1 :]
            d.status = "incomplete"
        elif i > 0:
            d.missing = sorted({*d.missing, pc}, key=self.order.__getitem__)
        if len(d.photocells) == 1:
            d.status = "aborted"
        self._event(e, line, pc, False,
                    f"{e.kind}: removed {pc} {when} from descent {d.number} (refitted)",
                    d.number)  # fmt: skip
        return [d], True

    def _enter(self, e: Edit, line: int, pc: str, bib: str) -> list[TimedDescent]:
        """An inserted or edited time: it enters the descent of its bib (or the one whose
        times it falls between), replacing that descent's time at the same photocell."""
        t = self._time(e.tod_us, e.day)
        k = self.order[pc]
        when = format_tod(e.tod_us)
        target = self._edit_target(t, k, pc, bib)
        if target is None:
            if k == 0:
                self._start_by_edit(e, line, pc, t, bib)
                return []
            self._event(e, line, pc, False,
                        f"{e.kind}: no descent{' of bib ' + bib if bib else ''} to enter "
                        f"{pc} {when} into; nothing changed")  # fmt: skip
            return []
        return self._enter_into(target, e, line, pc, t)

    def _edit_target(self, t: int, k: int, pc: str, bib: str) -> TimedDescent | None:
        """The descent an edited time at photocell ``pc`` (index ``k``) belongs to."""
        for d in [*reversed(self.open), *reversed(self.finished)]:
            if not d.times_us or (bib and d.bib != bib):
                continue
            if not bib:  # without a bib: the descent whose times it falls among
                if k == 0:  # a start typed in for a descent that has none
                    if d.photocells[0] == pc or not 0 < d.times_us[0] - t <= self.timeout_us[0]:
                        continue
                else:
                    j = self.order[d.photocells[-1]]
                    if not d.times_us[0] <= t <= d.times_us[-1] + self.timeout_us[j]:
                        continue
            if abs(t - d.times_us[0]) > max(self.timeout_us) * len(self.photocells):
                continue
            return d
        return None

    def _start_by_edit(self, e: Edit, line: int, pc: str, t: int, bib: str) -> None:
        """A start typed in at the timer that no descent has: it starts one."""
        when = format_tod(e.tod_us)
        self.count += 1
        d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[e.channel],
                         bib=bib, day=e.day)  # fmt: skip
        d.flags.append(f"start {when} {e.kind} at the timer")
        self.open.append(d)
        self._event(e, line, pc, True, f"{e.kind}: {pc} {when} starts descent "
                    f"{d.number}", d.number)  # fmt: skip

    def _enter_into(
        self, target: TimedDescent, e: Edit, line: int, pc: str, t: int
    ) -> list[TimedDescent]:
        """The edited time in its descent, in photocell order; the descent ends again if it
        now reaches the last photocell."""
        k = self.order[pc]
        when = format_tod(e.tod_us)
        d = target
        d.thaw()
        what = "entered"
        if pc in d.photocells:
            i = d.photocells.index(pc)
            old = d.times_us[i]
            d.times_us[i] = t
            d.channels[i] = e.channel
            what = f"replaced {format_tod(old % DAY_US)} at"
        else:
            i = sum(self.order[p] < k for p in d.photocells)
            d.photocells.insert(i, pc)
            d.times_us.insert(i, t)
            d.channels.insert(i, e.channel)
            if pc in d.missing:
                d.missing.remove(pc)
        if any(b <= a for a, b in zip(d.times_us, d.times_us[1:], strict=False)):
            del d.photocells[i], d.times_us[i], d.channels[i]
            self._event(e, line, pc, False, f"{e.kind}: {pc} {when} does not fit between the "
                        f"times of descent {d.number}; nothing changed", d.number)  # fmt: skip
            return []
        d.flags.append(f"{pc} {when} {e.kind} at the timer")
        is_open = d in self.open
        if d.photocells[-1] == self.photocells[-1] and len(d.photocells) >= 2:
            d.missing = [p for p in d.missing if p not in d.photocells]
            d.status = "complete" if d.photocells[0] == self.photocells[0] else "incomplete"
            if is_open:
                self.open.remove(d)
                self._done(d)
                is_open = False
        elif not is_open and len(d.photocells) >= 2 and d.status == "aborted":
            d.status = "incomplete"
        self._event(e, line, pc, True,
                    f"{e.kind}: {pc} {when} {what} descent {d.number}"
                    + ("" if is_open else " (refitted)"), d.number)  # fmt: skip
        return [] if is_open else [d]
