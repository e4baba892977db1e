"""Impulses -> descents: a pure state machine, no I/O and no clock of its own.

A descent starts with an impulse at the first photocell and ends at the last one, or when the
skier can no longer be on the run: ``timeout_s`` after the last impulse, or by default the
distance to the photocell after next at the slowest plausible speed. Then it is fitted with
the photocells it has and flagged. Several skiers may be on the run at once:

- **pairing** ``bib``: the number on a start and on later impulses pairs them, one open descent
  per bib; impulses without a valid bib (``?``, blank, zero) join descents without one.
  ``order``: the number is an impulse counter (ALGE PC-Timer) or absent; an impulse joins the
  open descent that can reach its photocell at a plausible speed (from the survey's distances
  and the descent's own speed so far; with several, the one closest to its expected time).
  ``auto`` decides at the first impulse after a start: the same number as an open descent's
  start means bibs, the previous impulse's number + 1 means a counter.
- an impulse that no open descent can reach plausibly joins nothing and starts nothing: it is
  rejected with the reason. A rejected impulse changes nothing: no clock, no time-out.
- **the device clock** (for the midnight wrap) moves only with impulses that were kept. An
  impulse more than ``jump_s`` away from it is held until the next impulse says whether the
  clock really jumped (a long break, the timer's clock set) or this one time is corrupted (one
  flipped hour digit would otherwise lose the day's later impulses); the host clock confirms
  it at once where the caller knows the device time (``now_us``).
- double triggers (legs, poles) at one photocell within ``debounce_s`` collapse to the first;
- a missed photocell leaves a gap: the descent goes on and is flagged;
- a lone start impulse that nothing follows (someone walking through the beam) is *aborted*;
- **edits** from the timer (ALGE ``c`` ``i``, TAG ``TC`` ``T+`` ``T*`` ``T-``) are applied: a
  cleared impulse leaves its descent, an inserted or edited time enters or replaces one, and a
  finished descent that changed comes out of ``feed``/``edit`` again to be refitted;
- an impulse repeated from the timer's memory (TAG ``AN``, ALGE ``m``) that is already kept
  (same channel, same time) is not doubled; one that is not is an impulse like any other;
- a disconnect is written on the open descents' flags;
- **a damaged start line**: the caller says which lines it could not parse or whose
  checksum failed (``note_damaged``). An impulse at a later photocell that no open descent can
  take starts a descent only when such a line came at a time that skier's start could have
  been (between the kept impulses around it, within the time to its photocell at the
  plausible speeds and the earlier descents' typical time), with bibs only for a bib with no
  open descent, and not at the last photocell (one time is nothing to fit). That descent is
  flagged, ``incomplete``, and fitted from the photocells it has; each damaged line starts at
  most one. Without a damaged line a stray impulse (someone walking through PC3) is
  rejected: one bit flipped in a start line does not lose the skier's whole descent.

Every impulse and edit comes out once in ``events`` with whether it was kept and why not.

One path decides every impulse: :meth:`DescentAssembler.feed_run` takes a run of them (what a
chunk's lines parsed to), and :meth:`DescentAssembler.feed` is a run of one. The parts live in
modules of their own: the device clock (:mod:`station.timing.device_clock`), pairing
(:mod:`station.timing.pairing`), damaged start lines (:mod:`station.timing.recovery`), the
timer's memory (:mod:`station.timing.memory`) and edits (:mod:`station.timing.edits`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from station.timing.assembler_base import PAIRINGS, AssemblerBase
from station.timing.descent import (
    DETAIL_CHARS,
    JOINED,
    REOPENED,
    ImpulseEvent,
    TimedDescent,
    bib_of,
    flag_damaged,
    is_joined,
    new_event,
    short_detail,
)
from station.timing.device_clock import HOST_TOLERANCE_US, SEEN_RECENT, DeviceClock
from station.timing.edits import ENTERING, REMOVING, Edits
from station.timing.impulses import DAMAGED_FLAG, DAY_US, Impulse
from station.timing.memory import MAX_ORPHANS, MemoryJoins
from station.timing.pairing import SPEED_RATIO, Pairing
from station.timing.recovery import Recovery

__all__ = [
    "DETAIL_CHARS", "ENTERING", "JOINED", "MAX_ORPHANS", "PAIRINGS", "REMOVING", "REOPENED",
    "SEEN_RECENT", "SPEED_RATIO", "AssemblerBase", "DescentAssembler", "ImpulseEvent",
    "TimedDescent", "is_joined", "short_detail",
]  # fmt: skip

#: the reason a repeat of a kept impulse is not kept
REPEATED = "repeats an impulse already kept (from the timer's memory?); not doubled"


class DescentAssembler(Edits, MemoryJoins, Recovery, Pairing, DeviceClock):
    """Feed impulses in arrival order; finished descents come back from ``feed`` and ``tick``."""

    def feed(self, imp: Impulse, line: int = 0, now_us: int | None = None) -> list[TimedDescent]:
        """One impulse in; the descents it finished out. ``now_us``: the device time now as the
        host clock estimates it, where known (it confirms a jump of the device clock)."""
        return self._run((imp,), 0, line, now_us, None, None)[1]

    def feed_run(
        self,
        items: Sequence[object],
        start: int,
        line: int,
        started: Callable[[TimedDescent], None] | None = None,
    ) -> tuple[int, list[TimedDescent], int]:
        """:meth:`feed` for ``items[start:]`` (what a chunk's lines parsed to; ``line``: the
        number of ``items[start]``, the next ones count on) without a host clock, up to the
        first item that is not an impulse or whose time needs the host clock or the next
        impulse to confirm it (far from the device clock, or one held for that): the caller
        hands that one to :meth:`feed` (or :meth:`edit`) and calls again after it. Each
        descent an impulse started goes to ``started`` once that impulse is decided. Returns
        the index of the item it stopped at (``len(items)`` at the end), the descents that
        finished, in order, and the index of the last impulse the device clock then stood at
        (-1: none; the caller pairs its host time with the clock).

        Why a run: a replay is a hundred thousand impulses, and the cost was mostly Python's
        per call (the state looked up again, a list made for each answer)."""
        return self._run(items, start, line, None, started, None, stop_unsure=True)

    def _run(  # noqa: C901, PLR0915 - the one loop every impulse goes through; a call per step costs the replay
        self, items: Sequence[object], start: int, line: int, now_us: int | None,
        started: Callable[[TimedDescent], None] | None, at: tuple[int, int | None] | None,
        stop_unsure: bool = False,
    ) -> tuple[int, list[TimedDescent], int]:  # fmt: skip
        """The one path: each impulse of ``items[start:]`` screened and accepted (``at``: time and
        previous number of one held, screened already); the common case here, the rare methods."""
        done: list[TimedDescent] = []
        kept_at, i = -1, start
        channels, seen_map, open_ = self._fast_channels, self._seen, self.open
        jump, debounce, last_k, event = self.jump_us, self.debounce_us, self._last_k, ImpulseEvent
        time_of, why_not, add_event = self._time, self._why_not, self.events.append
        for i in range(start, len(items)):  # noqa: B007 (the index it stopped at)
            imp = items[i]
            if type(imp) is not Impulse:
                break
            ln = line - start + i
            ch, tod, _res, flag, bib, day, _text = imp
            if at is None:
                prev = self._number(bib) if self.mode is None else None
                fast = channels.get(ch)
                t = time_of(tod, day)
                if (
                    fast is None
                    or t in seen_map.get(fast[0], ())
                    or (t <= self._old_max and self._kept_before(fast[0], t))
                ):
                    self._not_taken(imp, ln, fast, t)
                    kept_at = i if t == self._clock else kept_at  # (any line of its time)
                    continue
                ch, pc, k, _step = fast
                if (
                    self._pending is not None
                    or (c := self._clock) is not None
                    and abs(t - c) > jump
                ):
                    if stop_unsure:  # (the caller feeds it with the host clock's time)
                        self._prev_number = prev if self.mode is None else self._prev_number
                        break
                    if (sure := self._unsure(imp, ln, t, now_us, done)) is None:
                        continue
                    t = sure
            else:
                (t, prev), at, (ch, pc, k, _step) = at, None, channels[ch]
            last = self._last_done  # a double trigger (of the one that ended too)
            for twin in (open_[0], last) if len(open_) == 1 else (*open_, last):
                if twin and (ph := twin.photocells) and ph[-1] == pc and (
                        0 <= t - twin.times_us[-1] <= debounce):  # fmt: skip
                    self._collapse(twin, imp, ln, pc, t)
                    break
            else:
                mode = self.mode if self.mode is not None else self._decide_mode(k, imp, prev)
                d = open_[0] if k and len(open_) == 1 and not self.from_memory else None
                if k == 0:  # (the bib read where pairing by order does not ignore it)
                    b = "" if mode == "order" else bib_of(imp)
                    d, joined = self._begin(imp, ln, ch, pc, t, b, done, started)
                elif (
                    d is not None  # one candidate (:meth:`_choose`'s answer) takes it if it can
                    and (mode == "order" or ((b := bib_of(imp)) and d.bib == b))
                    and why_not(d, pc, k, t, mode == "order") is None
                ):
                    joined = ""
                else:  # several candidates, a rejection
                    d, joined = self._pair(imp, ln, ch, pc, k, t, done, started)
                if d is not None:  # d takes it: its time joined, the clock moved, its event
                    self._join(d, pc, k, t, ch)
                    self._clock, self._day_offset = t, t // DAY_US  # (_move_clock's common case)
                    if self._damaged:
                        self._move_clock(t)
                    add_event(new_event(event, (ln, ch, pc, tod, flag, True, joined, d.number)))
                    if flag == DAMAGED_FLAG:
                        flag_damaged(d, imp, ln)
                    if k == last_k:
                        done.append(self._complete(d))
                    if open_ and (len(open_) > 1 or open_[0] is not d):  # (d was updated now)
                        done += self._expire(t)
            kept_at = i if self._clock == t else kept_at
        else:
            i = len(items)
        return i, done, kept_at

    def _not_taken(
        self, imp: Impulse, line: int, fast: tuple[str, str, int, float | None] | None, t: int
    ) -> None:
        """An impulse at no photocell, or a repeat of one kept (the timer's memory again)."""
        if fast is None:
            self._event(imp, line, None, False, f"channel {imp.channel} is not a photocell")
        else:
            self._event(imp, line, fast[1], False, REPEATED)

    def _pair(
        self, imp: Impulse, line: int, ch: str, pc: str, k: int, t: int,
        done: list[TimedDescent], started: Callable[[TimedDescent], None] | None,
    ) -> tuple[TimedDescent | None, str]:  # fmt: skip
        """An impulse at a later photocell that is not the one candidate's to take: the one
        candidate rejecting it, several candidates (or an impulse from the timer's memory):
        the descent that takes it and the flag that says a memory impulse continued one
        recorded live (\"\"), or None: rejected, or it started a recovered descent."""
        bib = bib_of(imp)
        mode, open_ = self.mode, self.open
        reason = ""
        if (
            len(open_) == 1
            and (mode == "order" or (bib and open_[0].bib == bib))
            and not self.from_memory
        ):
            chosen = open_[0]
            why = self._why_not(chosen, pc, k, t, mode == "order")
            if why is None:
                return chosen, ""
            chosen, reason = None, why
        else:
            chosen, reason = self._choose(pc, k, t, bib)
        joined = ""  # the flag of a descent recorded live that this memory impulse continues
        if self.from_memory:
            chosen, joined = self._memory_join(chosen, pc, k, t, bib)
        if chosen is None:
            self._unjoined(imp, line, ch, pc, k, t, bib, reason, done, started)
        return chosen, joined

    def _unsure(
        self, imp: Impulse, line: int, t: int, now_us: int | None, done: list[TimedDescent]
    ) -> int | None:
        """An impulse while one is held for confirmation, or far from the device clock: the
        held one accepted when this one confirms its time (else rejected, its line possibly a
        damaged start), then this one held unless the host clock confirms its time. Its time
        (unwrapped again on the clock the held one moved), or None: held."""
        if self._pending is not None:
            p_imp, p_line, p_t = self._pending
            self._pending = None
            if 0 <= t - p_t <= self.jump_us:
                done += self._accept(p_imp, p_line, p_t, None)
                t = self.unwrap(imp)
            else:
                self._event(
                    p_imp, p_line, self.channels.get(p_imp.channel), False,
                    f"implausible time: {self._far(p_t)} the device clock, and the next "
                    "impulse does not confirm it (a corrupted time?); the clock did not move",
                )  # fmt: skip
                self.note_damaged(p_line)  # it may have been a start
        far = self._clock is not None and abs(t - self._clock) > self.jump_us
        if far and (now_us is None or abs(t - now_us) > HOST_TOLERANCE_US):
            self._pending = (imp, line, t)
            return None
        return t

    def _accept(
        self, imp: Impulse, line: int, t: int, prev_number: int | None
    ) -> list[TimedDescent]:
        """An impulse screened already (held for confirmation) accepted at ``t``."""
        return self._run((imp,), 0, line, None, None, (t, prev_number))[1]

    def _number(self, bib: str) -> int | None:
        """While the pairing is undecided: this impulse's number kept for the next one to be
        compared with (a counter counts on), and the one before it."""
        prev = self._prev_number
        self._prev_number = int(bib) if bib.isascii() and bib.isdigit() else None
        return prev

    def _collapse(self, d: TimedDescent, imp: Impulse, line: int, pc: str, t: int) -> None:
        """A double trigger of ``d`` at ``pc`` (legs, poles): collapsed to the first."""
        gap = t - d.times_us[-1]
        d.thaw()
        d.flags.append(f"double trigger at {pc} collapsed (+{gap / 1e6:.3f} s)")
        self._event(imp, line, pc, False, "double trigger within the debounce window", d.number)

    def _begin(
        self, imp: Impulse, line: int, ch: str, pc: str, t: int, bib: str,
        done: list[TimedDescent], started: Callable[[TimedDescent], None] | None,
    ) -> tuple[None, str]:  # fmt: skip
        """A start (to ``started``): a descent of the same bib still open ends (a start ends
        no descent by time: it may itself be a corrupted time; the next impulse that joins a
        descent, physics checked, a tick or the end will)."""
        by_bib = self.mode != "order"
        if by_bib and bib:
            for d in list(self.open):
                if d.bib == bib:
                    done += self._finish(d, f"ended by a new start of bib {bib}")
        self.count += 1
        d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[ch],
                         bib=bib if by_bib else "", day=imp.day)  # fmt: skip
        if self.from_memory:
            self._memory_starts.add(d.number)
        self.open.append(d)
        self._move_clock(t)
        self._keep(ch, t)
        self.events.append(
            new_event(ImpulseEvent, (line, ch, pc, imp.tod_us, imp.flag, True, "", d.number))
        )
        if imp.flag == DAMAGED_FLAG:
            flag_damaged(d, imp, line)
        if started is not None:
            started(d)
        return None, ""  # (nothing for the loop to take)

    def _unjoined(
        self, imp: Impulse, line: int, ch: str, pc: str, k: int, t: int, bib: str,
        reason: str, done: list[TimedDescent], started: Callable[[TimedDescent], None] | None,
    ) -> None:  # fmt: skip
        """An impulse no open descent takes: a descent whose start line was damaged (to
        ``started``), or rejected with the reason (and remembered for a descent from the
        memory to take)."""
        rec, why = self._recover(imp, line, pc, k, t, bib)
        if rec is not None:
            self.open.append(rec)
            self._move_clock(t)
            self._keep(ch, t)
            self._event(imp, line, pc, True, rec.flags[0], rec.number)
            done += self._expire(t)
            if started is not None:
                started(rec)
            return
        if not self.open:
            reason = f"{pc} without a start at {self.photocells[0]}"
        elif self._clock is not None and t < self._clock and reason.startswith("out of"):
            reason = f"out of order: {(self._clock - t) / 1e6:.4f} s earlier than the " \
                "previous impulse"  # fmt: skip
        if why:
            reason = f"{reason}; {why}"
        self._event(imp, line, pc, False, reason, self._near(bib))
        if not self.from_memory:
            self._orphans.append((pc, k, t, ch, bib, line, imp.tod_us, imp.flag))
            del self._orphans[:-MAX_ORPHANS]

    def _join(self, d: TimedDescent, pc: str, k: int, t: int, ch: str) -> None:
        """Photocell ``pc`` (index ``k``) at ``t`` on channel ``ch`` taken into descent ``d``:
        the photocells it skipped flagged and listed missing, the time kept against repeats.
        One method for a live impulse joining its descent and a live one taken into a
        descent begun in the timer's memory (:meth:`_adopt`): a descent's missed photocells
        read the same either way."""
        photocells = d.photocells
        j = self.order[photocells[-1]]
        if k > j + 1:
            skipped = self.photocells[j + 1 : k]
            d.flags.append(f"missed {', '.join(skipped)}")
            d.missing += skipped
        photocells.append(pc)
        d.times_us.append(t)
        d.channels.append(ch)
        seen = self._seen.get(ch)  # (as _keep, on a replay's every impulse)
        if seen is None:
            seen = self._seen[ch] = set()
        seen.add(t)

    def _expire(self, t: int) -> list[TimedDescent]:
        done: list[TimedDescent] = []
        for d in list(self.open):
            j = self.order[d.photocells[-1]]
            if t - d.times_us[-1] > self.timeout_us[j]:
                done += self._finish(
                    d, f"no impulse for {(t - d.times_us[-1]) / 1e6:.1f} s after {d.photocells[-1]}"
                )
        return done

    def tick(self, now_us: int) -> list[TimedDescent]:
        """Device time now (estimated from the host clock): end descents that timed out."""
        return self._expire(now_us)

    def close(self) -> list[TimedDescent]:
        """End of the capture: a held impulse is taken as it is, open descents end here."""
        done: list[TimedDescent] = []
        if self._pending is not None:
            p_imp, p_line, p_t = self._pending
            self._pending = None
            done += self._accept(p_imp, p_line, p_t, None)
        for d in list(self.open):
            done += self._finish(d, "the recording ended")
        return done

    def memory_follows(self) -> list[TimedDescent]:
        """The impulses that follow are from the timer's memory (:attr:`from_memory`): a live
        impulse still held for the next one to confirm its time is taken as it is first, as
        at the end of a capture (:meth:`close`); the descents that ended."""
        done = self._take_held()
        self.from_memory = True
        return done

    def _take_held(self) -> list[TimedDescent]:
        """The impulse held for the next one to confirm its time, taken as it is (a memory
        impulse, earlier by nature, would call it a corrupted time)."""
        if self._pending is None:
            return []
        p_imp, p_line, p_t = self._pending
        self._pending = None
        return self._accept(p_imp, p_line, p_t, None)

    def disconnected(self, detail: str = "") -> None:
        """The connection to the timer broke: the open descents say so, once each and in a
        few words (the raw log keeps the port's full message; a descent's flags are read in a
        table cell, where pyserial's sentence, repeated at every reconnection, hid the rest)."""
        flag = "timer disconnected" + (f" ({short_detail(detail)})" if detail else "")
        for d in self.open:
            if flag not in d.flags:
                d.flags.append(flag)

    def _complete(self, d: TimedDescent) -> TimedDescent:
        """``d`` took the last photocell: it ends (one recovered without its start is short
        of the first)."""
        self.open.remove(d)
        d.status = "complete" if d.photocells[0] == self.photocells[0] else "incomplete"
        self._done(d)
        return d

    def _done(self, d: TimedDescent) -> None:
        self.finished.append(d)
        self._last_done = d
        self._settle_seen()
        if d.status == "complete":
            self._record_typical(d)

    def _finish(self, d: TimedDescent, why: str) -> list[TimedDescent]:
        self.open.remove(d)
        from_memory = self.from_memory or d.number in self._memory_starts
        if from_memory and self._orphans and self._adopt(d):
            d.status = "complete" if d.photocells[0] == self.photocells[0] else "incomplete"
            self._done(d)
            return [d]
        if len(d.photocells) == 1:
            d.status = "aborted"
            lone = "start impulse" if d.photocells[0] == self.photocells[0] else "impulse"
            d.flags.append(f"lone {lone}, {why}")
        else:
            d.status = "incomplete"
            last = self.order[d.photocells[-1]]
            tail = self.photocells[last + 1 :]
            d.missing += tail
            d.flags.append(f"{why}; missing {', '.join(tail)}")
        self._short.append(d)
        self._done(d)
        return [d]
