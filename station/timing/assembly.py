"""Impulses -> descents: a pure state machine, no I/O and no clock of its own.

A descent starts with an impulse at the first photocell and ends at the last one, or when the
skier can no longer be on the run: ``timeout_s`` after the last impulse, or by default the
distance to the photocell after next at the slowest plausible speed. Then it is fitted with
the photocells it has and flagged. Several skiers may be on the run at once (issue 11):

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
  clock really jumped (a long break, the timer's clock set) or this one time is corrupted
  (issue 9: one flipped hour digit lost 18 165 impulses); the host clock confirms it at once
  where the caller knows the device time (``now_us``).
- double triggers (legs, poles) at one photocell within ``debounce_s`` collapse to the first;
- a missed photocell leaves a gap: the descent goes on and is flagged;
- a lone start impulse that nothing follows (someone walking through the beam) is *aborted*;
- **edits** from the timer (ALGE ``c`` ``i``, TAG ``TC`` ``T+`` ``T*`` ``T-``) are applied: a
  cleared impulse leaves its descent, an inserted or edited time enters or replaces one, and a
  finished descent that changed comes out of ``feed``/``edit`` again to be refitted;
- an impulse repeated from the timer's memory (TAG ``AN``, ALGE ``m``) that is already kept
  (same channel, same time) is not doubled; one that is not is an impulse like any other;
- a disconnect is written on the open descents' flags;
- **a damaged start line** (issue 9): the caller says which lines it could not parse or whose
  checksum failed (``note_damaged``). An impulse at a later photocell that no open descent can
  take starts a descent only when such a line came at a time that skier's start could have
  been (between the kept impulses around it, within the time to its photocell at the
  plausible speeds and the earlier descents' typical time), with bibs only for a bib with no
  open descent, and not at the last photocell (one time is nothing to fit). That descent is
  flagged, ``incomplete``, and fitted from the photocells it has; each damaged line starts at
  most one. Without a damaged line a stray impulse (someone walking through PC3) is rejected
  as before: one bit flipped in a start line no longer loses the skier's whole descent.

Every impulse and edit comes out once in ``events`` with whether it was kept and why not.
"""

from __future__ import annotations

from array import array
from bisect import bisect_left
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple

from station.timing.impulses import (
    DAMAGED_FLAG,
    DAY_US,
    MEMORY_REPEAT,
    Edit,
    Impulse,
    format_tod,
)

HALF_DAY_US = DAY_US // 2
PAIRINGS = ("auto", "bib", "order")
#: the kinds of edit that remove an impulse, enter one, or only repeat one
REMOVING = {"cleared", "memory time deleted", "disqualified", "cancelled",
            "identification removed"}  # fmt: skip
ENTERING = {"edited", "inserted"}
#: a speed between two photocells may be this factor off the speed before (order pairing)
SPEED_RATIO = 2.5
#: the host clock confirms a jump of the device clock within this (µs)
HOST_TOLERANCE_US = 30_000_000


@dataclass(slots=True)
class TimedDescent:
    """One skier's pass: the kept time at each photocell (µs, unwrapped across midnight).
    Every descent of a day is kept (edits may name any): slots."""

    number: int
    photocells: list[str]  # the photocells with a time, in order down the run
    times_us: list[int]
    status: str = "open"  # complete | incomplete | aborted
    flags: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    first_line: int = 0
    bib: str = ""  # the start's number when it is a bib (not a counter)
    channels: list[str] = field(default_factory=list)  # the timer channel of each time
    day: int | None = None  # days since 2000-01-01 of the start, where the device says (TAG)
    first_us: int | None = None  # the first time it had (its times may all be cleared)

    def __post_init__(self) -> None:
        if self.first_us is None and self.times_us:
            self.first_us = self.times_us[0]

    @property
    def start_us(self) -> int:
        return self.times_us[0] if self.times_us else (self.first_us or 0)

    def settle(self, kept: Any) -> None:
        """The caller took a frozen copy of this finished descent (``kept``, a
        :class:`station.session.records.DescentTimes`: the same values as tuples): it keeps
        those tuples in place of its lists, one copy of each for the day, not two (a day's
        descents stay in memory: edits may name any of them). The assembler makes them lists
        again (:meth:`thaw`) before it changes the descent. A descent open again (its finish
        cleared at the timer later in the same chunk) keeps its lists."""
        if self.status == "open":
            return
        for name in _LISTS:
            mine, theirs = getattr(self, name), getattr(kept, name)
            if type(theirs) is tuple and len(mine) == len(theirs) and tuple(mine) == theirs:
                setattr(self, name, theirs)

    def thaw(self) -> None:
        """Lists again where :meth:`settle` left tuples: before any change to the descent."""
        for name in _LISTS:
            v = getattr(self, name)
            if type(v) is tuple:
                setattr(self, name, list(v))


#: how the flag of a descent the timer's memory completed begins (``station import`` says it)
JOINED = "joined: "
#: how the flag of a descent from the timer's memory that the memory itself reopened begins
#: (not joined: all its crossings are the memory's)
REOPENED = "reopened: "
#: live impulses no descent took, remembered for a descent from the memory to take
MAX_ORPHANS = 200
#: the fields of a descent that are lists while the assembler may change them
_LISTS = ("photocells", "times_us", "flags", "missing", "channels")
#: kept times a channel holds in its set before the older ones move to its sorted array
#: (8 bytes a time, not ~70): a repeat of any kept impulse is found all day
SEEN_RECENT = 64


def is_joined(d: TimedDescent) -> bool:
    """Whether ``d`` says it was joined (live crossings and the timer's memory in one)."""
    return any(f.startswith(JOINED) for f in d.flags)


def _live_then_memory(last: str, pc: str) -> str:
    """The flag of a descent recorded live up to ``last`` and from the timer's memory on
    from ``pc``: one wording whether the memory reopened it or continued it."""
    return f"{JOINED}{last} recorded live, {pc} on from the timer's memory"


@dataclass
class _Damage:
    """A line the caller could not read: where it came in the device's time."""

    line: int
    after_us: int | None  # the device clock when it came: its time was not earlier
    before_us: int | None = None  # the first time kept after it: its time was not later


#: damaged lines remembered for recovering a start (a flood of noise keeps the latest)
MAX_DAMAGED = 200


class ImpulseEvent(NamedTuple):
    """What became of one impulse (or edit line)."""

    line: int
    channel: str
    photocell: str | None
    tod_us: int
    flag: str
    kept: bool
    reason: str = ""
    descent: int | None = None


def _flag_damaged(d: TimedDescent, imp: Impulse, line: int) -> None:
    """A kept impulse read from a line with a damaged flag byte: the descent says so."""
    if imp.flag == DAMAGED_FLAG:
        d.flags.append(f"line {line}: flag byte {imp.line[:1]!r} damaged, read as an impulse")


#: an event made without the NamedTuple's Python-level ``__new__`` (a plain tuple's cost, the
#: same record: a day's replay makes one per impulse)
_new_event = tuple.__new__


def _median(values: list[int]) -> float:
    """``statistics.median`` of a few ints, without its generality (one per photocell of every
    complete descent in a replay)."""
    s = sorted(values)
    m = len(s) // 2
    return s[m] if len(s) % 2 else (s[m - 1] + s[m]) / 2


def _bib(imp: Impulse | Edit) -> str:
    """A valid bib: digits, not all zeros, not flagged ``?`` (time without valid number)."""
    if imp.flag == "?":
        return ""
    return imp.bib.strip().lstrip("0")


class DescentAssembler:
    """Feed impulses in arrival order; finished descents come back from ``feed`` and ``tick``."""

    def __init__(
        self,
        photocells: list[str],
        channels: dict[str, str],
        debounce_s: float = 0.3,
        timeout_s: float | None = None,
        positions_m: list[float] | None = None,
        min_speed_ms: float = 1.0,
        max_speed_ms: float = 45.0,
        pairing: str = "auto",
        jump_s: float | None = None,
    ) -> None:
        if pairing not in PAIRINGS:
            raise ValueError(f"unknown pairing {pairing!r} ({', '.join(PAIRINGS)})")
        # only photocells wired to a channel can have times: a descent ends at the last of
        # them, and its time-outs run to the wired photocell after next
        wired = set(channels.values())
        keep = [i for i, pc in enumerate(photocells) if pc in wired] or list(range(len(photocells)))
        photocells = [photocells[i] for i in keep]
        if positions_m is not None:
            positions_m = [positions_m[i] for i in keep]
        self.order = {pc: i for i, pc in enumerate(photocells)}
        self.photocells = list(photocells)
        self.channels = dict(channels)
        self._channel_names = {ch: ch for ch in self.channels}
        self.debounce_us = round(debounce_s * 1e6)
        self.positions = list(positions_m) if positions_m is not None else None
        self.min_speed = min_speed_ms
        self.max_speed = max_speed_ms
        n = len(photocells)
        if timeout_s is not None:
            self.timeout_us = [round(timeout_s * 1e6)] * n
        elif positions_m is not None:
            # the skier must reach the photocell after next (one may be missed) at min_speed
            self.timeout_us = [
                round((positions_m[min(j + 2, n - 1)] - positions_m[j]) / min_speed_ms * 1e6)
                for j in range(n)
            ]
        else:
            self.timeout_us = [60_000_000] * n
        self.jump_us = (
            round(jump_s * 1e6) if jump_s is not None else max(60_000_000, *self.timeout_us)
        )
        self.pairing = pairing
        self.mode: str | None = None if pairing == "auto" else pairing
        #: channel -> (the config's string for it, photocell, its index, the distance from the
        #: photocell before, m): what the fast path needs of an impulse's channel, in one look-up
        self._fast_channels: dict[str, tuple[str, str, int, float | None]] = {
            ch: (ch, pc, k, None if k == 0 or self.positions is None
                 else self.positions[k] - self.positions[k - 1])
            for ch, pc in self.channels.items()
            if (k := self.order.get(pc)) is not None
        }  # fmt: skip
        self._last_k = n - 1
        self.open: list[TimedDescent] = []
        self.finished: list[TimedDescent] = []
        self.count = 0
        self.events: list[ImpulseEvent] = []
        self._day_offset = 0
        self._clock: int | None = None  # unwrapped time of the latest kept impulse
        self._pending: tuple[Impulse, int, int] | None = None
        self._prev_number: int | None = None
        # photocell index -> the last 10 complete descents' t_k - t_0
        self._typical: dict[int, deque[int]] = {}
        # their medians, computed when asked for after the history changed (``_stale``): a
        # replay ends thousands of descents and asks for few of them
        self._typical_mid: dict[int, float] = {}
        self._stale: set[int] = set()
        self._last_done: TimedDescent | None = None
        # kept impulses by channel and device time (unwrapped): a repeat of one (the timer's
        # memory sent again) is not doubled, while the same time of day a day later is new
        self._seen: dict[str, set[int]] = {}  # channel -> its kept times
        # the older ones, sorted (moved there as descents end), and the latest of them all
        self._seen_old: dict[str, array[int]] = {}
        self._old_max = -1
        self._damaged: list[_Damage] = []  # unread lines that may have been a start
        #: the impulses come from the timer's memory (a download merged by ``station import``,
        #: or sent between TAG ``DS`` and ``DE``, an ALGE ``m`` line): one no open descent
        #: takes may be the rest of a descent that ended for want of it (the cable was out)
        self.from_memory = False
        #: the descents that ended short of the last photocell (timed out, disconnected, a new
        #: start of the bib, the end): those the timer's memory may complete
        self._short: list[TimedDescent] = []
        #: live impulses no descent took (past a start the cable lost): (photocell, its index,
        #: time, channel, bib, and the line, time of day and flag its event had), the latest
        #: MAX_ORPHANS; a descent from the timer's memory that ends short of them takes those
        #: that continue it (of its own bib, when bibs pair)
        self._orphans: list[tuple[str, int, int, str, str, int, int, str]] = []
        #: descents started by an impulse from the timer's memory (ALGE ``m`` lines end with
        #: the line: such a descent still takes the live rest when it ends short later)
        self._memory_starts: set[int] = set()

    @property
    def current(self) -> TimedDescent | None:
        """The open descent started last (the UI shows it)."""
        return self.open[-1] if self.open else None

    # -- time

    @property
    def clock(self) -> int | None:
        """Device time of the latest accepted impulse (µs, unwrapped); None before the first."""
        return self._clock

    def _time(self, tod_us: int, day: int | None) -> int:
        """Time of day -> device time in µs on the clock's day (midnight wraps forward).
        Pure: the clock moves only when an impulse is kept."""
        if day is not None:
            return day * DAY_US + tod_us
        t = self._day_offset * DAY_US + tod_us
        if self._clock is not None and t < self._clock - HALF_DAY_US:
            t += DAY_US
        return t

    def unwrap(self, imp: Impulse) -> int:
        return self._time(imp.tod_us, imp.day)

    def _move_clock(self, t: int) -> None:
        self._clock = t
        self._day_offset = t // DAY_US
        for dmg in reversed(self._damaged):
            if dmg.before_us is not None:
                break
            dmg.before_us = t

    # -- damaged lines

    def note_damaged(self, line: int) -> None:
        """Line ``line`` could not be read (unparsed, a failed checksum, a corrupted time): it
        may have been a skier's start, so an impulse after it may start a descent without one."""
        self._damaged.append(_Damage(line, self._clock))
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

    def _damaged_start(self, line: int, k: int, t: int) -> _Damage | None:
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

    # -- impulses

    def _event(self, imp, line: int, pc, kept: bool, reason: str = "", descent=None) -> None:
        self.events.append(
            _new_event(
                ImpulseEvent, (line, imp.channel, pc, imp.tod_us, imp.flag, kept, reason, descent)
            )
        )

    def feed(self, imp: Impulse, line: int = 0, now_us: int | None = None) -> list[TimedDescent]:
        """One impulse in; the descents it finished out. ``now_us``: the device time now as the
        host clock estimates it, where known (it confirms a jump of the device clock)."""
        # the common cases first: the one open descent reaching its next photocell, and the
        # next skier's start with no descent open
        fast = self._fast_channels.get(imp.channel)
        if fast is not None and self._pending is None:
            n_open = len(self.open)
            if n_open == 1:
                done = self._next_photocell(imp, line, fast)
                if done is not None:
                    return done
            elif n_open == 0 and fast[2] == 0 and self._start(imp, line, fast):
                return []
        return self._feed(imp, line, now_us)

    def _start(self, imp: Impulse, line: int, fast: tuple[str, str, int, float | None]) -> bool:
        """The fast path of a start with no descent open (the pairing decided, the time near
        the clock, no repeat, no double trigger of the descent that just ended): the descent
        starts, as :meth:`_accept` starts it. False, having changed nothing, otherwise."""
        mode = self.mode
        if mode is None or imp.day is not None:
            return False
        ch, pc, _k, _step = fast
        tod = imp.tod_us
        t = self._fast_time(ch, pc, tod)
        if t is None:
            return False
        flag = imp.flag
        bib = "" if mode == "order" or flag == "?" else imp.bib.strip().lstrip("0")
        self.count += 1
        d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[ch], bib=bib)
        if self.from_memory:
            self._memory_starts.add(d.number)
        self.open.append(d)
        self._fast_keep(line, ch, pc, tod, flag, t, d.number)
        if flag == DAMAGED_FLAG:
            _flag_damaged(d, imp, line)
        return True

    def _fast_time(self, ch: str, pc: str, tod: int) -> int | None:
        """The device time of an impulse at ``pc`` (channel ``ch``, ``tod`` its time of day)
        that a fast path (:meth:`_start`, :meth:`_next_photocell`) may keep, or None where
        the general path must look: no clock yet, the time far from the clock, a repeat of a
        kept impulse or a time as old as the sorted kept ones, a double trigger of the
        descent that just ended. One unwrap, as :meth:`_time` does it without a day counter.
        Why one method: the two fast paths checked this line for line alike, and must go on
        agreeing with each other and with :meth:`feed_run` (which has it inline: its loop is a
        replay's every impulse)."""
        clock = self._clock
        if clock is None:
            return None
        t = self._day_offset * DAY_US + tod
        if t < clock - HALF_DAY_US:
            t += DAY_US
        jump = self.jump_us
        if not -jump <= t - clock <= jump:
            return None
        seen = self._seen.get(ch)
        if (seen is not None and t in seen) or t <= self._old_max:
            return None  # (a time as old as the sorted kept ones: the general path looks)
        last_done = self._last_done
        if (
            last_done is not None
            and last_done.photocells
            and last_done.photocells[-1] == pc
            and 0 <= t - last_done.times_us[-1] <= self.debounce_us
        ):
            return None  # a double trigger of the descent that just ended
        return t

    def _fast_keep(
        self, line: int, ch: str, pc: str, tod: int, flag: str, t: int, number: int
    ) -> None:
        """What a fast path leaves for an impulse it kept (descent ``number``): the clock at its
        time, the time kept against repeats, its event, as :meth:`_accept` leaves them; one
        method for both fast paths, which had it word for word."""
        self._move_clock(t)
        self._keep(ch, t)
        self.events.append(_new_event(ImpulseEvent, (line, ch, pc, tod, flag, True, "", number)))

    def _feed(self, imp: Impulse, line: int, now_us: int | None) -> list[TimedDescent]:
        """:meth:`feed`'s general path: every impulse the fast path does not take."""
        ch = imp.channel
        pc = self.channels.get(ch)
        if pc is not None:
            ch = self._channel_names[ch]  # the config's string, kept: not one per line
            if ch is not imp.channel:
                imp = imp._replace(channel=ch)
        done: list[TimedDescent] = []
        number = int(imp.bib) if imp.bib.isascii() and imp.bib.isdigit() else None
        prev_number, self._prev_number = self._prev_number, number
        if pc is None:
            self._event(imp, line, None, False, f"channel {ch} is not a photocell")
            return done
        t = self.unwrap(imp)
        if t in self._seen.get(ch, ()) or (t <= self._old_max and self._kept_before(ch, t)):
            self._event(imp, line, pc, False, "repeats an impulse already kept (from the "
                        "timer's memory?); not doubled")  # fmt: skip
            return done
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
            return done
        return done + self._accept(imp, line, t, prev_number)

    def _next_photocell(
        self, imp: Impulse, line: int, fast: tuple[str, str, int, float | None]
    ) -> list[TimedDescent] | None:
        """The fast path of :meth:`feed` (a replay's every impulse but the starts): the one open
        descent takes the impulse at its next photocell. It decides as the general path would
        (:meth:`_accept` and :meth:`_choose` with one candidate) and returns None, having
        changed nothing, wherever that needs more than this: the pairing still undecided, a
        bib of another descent, a photocell skipped, a time far from the clock, a repeat, a
        double trigger of the descent that just ended, or a reason to reject it. One unwrap,
        no list copied, no closure, the event a plain tuple."""
        _chn, tod, _res, flag, bib, day, _text = imp
        if flag == DAMAGED_FLAG:
            return None  # its descent says so (_accept): the general path
        mode = self.mode
        d = self.open[0]
        if self.from_memory and d.number not in self._memory_starts:
            return None  # the memory continues a descent recorded live: it says so (_accept)
        if mode == "bib":
            if flag == "?" or not d.bib or bib.strip().lstrip("0") != d.bib:
                return None
        elif mode != "order":
            return None
        if day is not None:
            return None
        ch, pc, k, step_m = fast
        photocells = d.photocells
        j = k - 1
        if self.order[photocells[-1]] != j:
            return None
        t = self._fast_time(ch, pc, tod)
        if t is None:
            return None
        # what _why_not checks for the next photocell, in its words (no call: every impulse)
        times = d.times_us
        last = times[-1]
        gap = t - last
        if gap <= 0 or gap > self.timeout_us[j]:
            return None
        if step_m is not None:
            v = step_m / (gap / 1e6)
            if v > self.max_speed:
                return None
            if mode == "order" and len(photocells) >= 2:
                pos = self.positions
                assert pos is not None
                i = self.order[photocells[-2]]
                dt = (last - times[-2]) / 1e6
                if dt > 0:
                    v_before = (pos[j] - pos[i]) / dt
                    if not v_before / SPEED_RATIO <= v <= v_before * SPEED_RATIO:
                        return None
        photocells.append(pc)
        times.append(t)
        d.channels.append(ch)
        self._fast_keep(line, ch, pc, tod, flag, t, d.number)
        if k != self._last_k:
            return []  # the descent goes on; it was updated now, so nothing times out
        self.open.clear()
        d.status = "complete" if photocells[0] == self.photocells[0] else "incomplete"
        self._done(d)
        return [d]

    def feed_run(
        self, items: Sequence[object], start: int, line: int
    ) -> tuple[int, list[TimedDescent], list[TimedDescent]]:
        """:meth:`feed` for ``items[start:]`` (what a chunk's lines parsed to; ``line``: the
        number of ``items[start]``, the next ones count on) in one loop, as far as each item is
        an impulse of the common case: with no descent open a start, with one open descent
        the impulse at its next photocell, both as the fast paths (:meth:`_start`,
        :meth:`_next_photocell`) take them. It stops, having changed nothing for it, at the
        first item that is not: an edit or any other line, a second skier on the run, a bib
        of another descent, a photocell skipped, a time far from the clock, a repeat, a double
        trigger, a damaged flag, a reason to reject it; the caller hands that one to
        :meth:`feed` (or :meth:`edit`) and calls again after it. Returns the index of the
        item it stopped at (``len(items)`` at the end), the descents that finished and the
        descents that started, in order.

        Why: a replay is a hundred thousand impulses, and the fast paths' cost was mostly
        Python's per call: the attributes looked up again, a tuple unpacked, a list made for
        each answer. Here the assembler's state stays in local variables for the run, the
        open descent's lists are at hand, and its speed between the last two photocells is
        the one computed for the impulse before (the same float). The decisions are
        :meth:`_next_photocell`'s and :meth:`_start`'s, condition for condition
        (tests/test_assembly_batch.py checks the events and descents against the general
        path on the real captures and on random streams)."""
        done: list[TimedDescent] = []
        started: list[TimedDescent] = []
        n = len(items)
        mode = self.mode
        clock = self._clock
        open_ = self.open
        if (
            start >= n
            or self._pending is not None
            or mode is None
            or clock is None
            or len(open_) > 1
        ):
            return start, done, started
        memory = self.from_memory
        memory_starts = self._memory_starts
        if memory and open_ and open_[0].number not in memory_starts:
            return start, done, started  # (see _next_photocell)
        by_order = mode == "order"  # else "bib" (mode is decided and changes on no fast path)
        fast_channels = self._fast_channels
        seen_map = self._seen
        events_append = self.events.append
        jump = self.jump_us
        debounce = self.debounce_us
        timeouts = self.timeout_us
        max_speed = self.max_speed
        first_pc = self.photocells[0]
        last_k = self._last_k
        damaged = bool(self._damaged)  # changed by note_damaged and _recover: not in here
        old_max = self._old_max
        last_done = self._last_done
        ld_pc: str | None = None  # the last photocell and time of the descent that ended last
        ld_t = 0
        if last_done is not None and last_done.photocells:
            ld_pc, ld_t = last_done.photocells[-1], last_done.times_us[-1]
        day_us, half_day_us, damaged_flag, ratio = DAY_US, HALF_DAY_US, DAMAGED_FLAG, SPEED_RATIO
        new_event, event, impulse = _new_event, ImpulseEvent, Impulse
        base = self._day_offset * day_us
        low = clock - half_day_us
        d: TimedDescent | None = None
        photocells: list[str] = []
        times: list[int] = []
        add_pc, add_t, add_ch = photocells.append, times.append, photocells.append  # (its own)
        number = 0
        d_bib = ""
        j = -1  # the index of the open descent's last photocell
        last = 0  # and its last time
        # its speed into photocell j, where the order pairing checks the next one against it:
        # the speed this loop computed for the impulse before (the very float _why_not has)
        v_prev: float | None = None
        line0 = line - start  # the line of items[i]: line0 + i
        if open_:
            d = open_[0]
            photocells, times = d.photocells, d.times_us
            add_pc, add_t, add_ch = photocells.append, times.append, d.channels.append
            number, d_bib, j, last = d.number, d.bib, self.order[photocells[-1]], times[-1]
            pos = self.positions
            if by_order and pos is not None and len(times) >= 2 and last > times[-2]:
                i_before = self.order[photocells[-2]]
                v_prev = (pos[j] - pos[i_before]) / ((last - times[-2]) / 1e6)
        next_base = base + day_us
        for i in range(start, n):
            imp = items[i]
            if type(imp) is not impulse:
                break
            ch, tod, _res, flag, bib, day, _text = imp
            fast = fast_channels.get(ch)
            if fast is None or day is not None or flag == damaged_flag:
                break
            ch, pc, k, step_m = fast
            t = base + tod  # the one unwrap (see _time)
            if t < low:
                t += day_us
            if not -jump <= t - clock <= jump:
                break
            seen = seen_map.get(ch)
            if (seen is not None and t in seen) or t <= old_max:
                break
            if ld_pc == pc and 0 <= t - ld_t <= debounce:
                break  # a double trigger of the descent that just ended
            if d is None:
                if k != 0:
                    break
                self.count += 1
                number = self.count
                d_bib = "" if by_order or flag == "?" else bib.strip().lstrip("0")
                d = TimedDescent(number, [pc], [t], first_line=line0 + i, channels=[ch],
                                 bib=d_bib)  # fmt: skip
                if memory:
                    memory_starts.add(number)
                open_.append(d)
                started.append(d)
                photocells, times = d.photocells, d.times_us
                add_pc, add_t, add_ch = photocells.append, times.append, d.channels.append
                j, last, v_prev = 0, t, None
            else:
                if k != j + 1:
                    break
                if not by_order and (flag == "?" or not d_bib or bib.strip().lstrip("0") != d_bib):
                    break
                gap = t - last
                if gap <= 0 or gap > timeouts[j]:
                    break
                if step_m is not None:
                    v = step_m / (gap / 1e6)
                    if v > max_speed:
                        break
                    if v_prev is not None and not v_prev / ratio <= v <= v_prev * ratio:
                        break
                    if by_order:
                        v_prev = v
                add_pc(pc)
                add_t(t)
                add_ch(ch)
                j, last = k, t
            if damaged:
                self._move_clock(t)  # (its clock, day and the damaged lines' times)
            clock = t  # (the assembler's is set when the run ends or a descent does)
            low = t - half_day_us
            if t >= next_base:  # (t is never before base: base + a time of day)
                base = t // day_us * day_us
                next_base = base + day_us
            if seen is None:
                seen = seen_map[ch] = set()
            seen.add(t)
            events_append(new_event(event, (line0 + i, ch, pc, tod, flag, True, "", number)))
            if k == last_k:
                open_.clear()
                d.status = "complete" if photocells[0] == first_pc else "incomplete"
                self._clock, self._day_offset = clock, clock // day_us
                self._done(d)
                done.append(d)
                old_max = self._old_max
                ld_pc, ld_t = pc, t
                d = None
        else:
            i = n
        if i > start:
            self._clock, self._day_offset = clock, clock // day_us
        return i, done, started

    def _keep(self, channel: str, t: int) -> None:
        """A kept impulse: a repeat of it (the timer's memory sent again) is not doubled."""
        seen = self._seen.get(channel)
        if seen is None:
            seen = self._seen[channel] = set()
        seen.add(t)

    def _far(self, t: int) -> str:
        assert self._clock is not None
        d = (t - self._clock) / 1e6
        word = "after" if d > 0 else "before"
        d = abs(d)
        amount = f"{d / 3600:.2f} h" if d >= 3600 else f"{d:.1f} s"
        return f"{amount} {word}"

    def _accept(
        self, imp: Impulse, line: int, t: int, prev_number: int | None
    ) -> list[TimedDescent]:
        """An impulse whose time is plausible for the clock: join, start or reject."""
        done: list[TimedDescent] = []
        pc = self.channels[imp.channel]
        k = self.order[pc]
        # a double trigger of an open descent or of the one that just finished
        for d in [*self.open, self._last_done]:
            if d is None or not d.photocells or d.photocells[-1] != pc:
                continue
            gap = t - d.times_us[-1]
            if 0 <= gap <= self.debounce_us:
                d.thaw()
                d.flags.append(f"double trigger at {pc} collapsed (+{gap / 1e6:.3f} s)")
                self._event(imp, line, pc, False, "double trigger within the debounce window",
                            d.number)  # fmt: skip
                return done
        bib = _bib(imp)
        if self.mode is None and k > 0 and bib and self.open:
            if any(d.bib == bib for d in self.open):
                self.mode = "bib"
            elif prev_number is not None and int(bib) == (prev_number + 1) % 10000:
                self.mode = "order"  # an impulse counter, not a bib
                for d in self.open:
                    d.bib = ""
        if k == 0:
            # a start ends no descent by time: it may itself be a corrupted time; the next
            # impulse that joins a descent (physics checked), a tick or the end will
            if self.mode != "order" and bib:
                for d in list(self.open):
                    if d.bib == bib:
                        done += self._finish(d, f"ended by a new start of bib {bib}")
            self.count += 1
            d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[imp.channel],
                             bib=bib if self.mode != "order" else "", day=imp.day)  # fmt: skip
            if self.from_memory:
                self._memory_starts.add(d.number)
            self.open.append(d)
            self._move_clock(t)
            self._keep(imp.channel, t)
            self._event(imp, line, pc, True, "", d.number)
            _flag_damaged(d, imp, line)
            return done
        chosen, reason = self._choose(pc, k, t, bib)
        joined = ""  # the flag of a descent recorded live that this memory impulse continues
        if self.from_memory:
            if chosen is None:
                chosen = self._rejoin(pc, k, t, bib)
                if chosen is not None:
                    joined = chosen.flags[-1]
            else:
                joined = self._continued(chosen, pc)
        if chosen is None:
            rec, why = self._recover(imp, line, pc, k, t, bib)
            if rec is not None:
                self.open.append(rec)
                self._move_clock(t)
                self._keep(imp.channel, t)
                self._event(imp, line, pc, True, rec.flags[0], rec.number)
                return done + self._expire(t)
            if not self.open:
                reason = f"{pc} without a start at {self.photocells[0]}"
            elif self._clock is not None and t < self._clock and reason.startswith("out of"):
                reason = f"out of order: {(self._clock - t) / 1e6:.4f} s earlier than the " \
                    "previous impulse"  # fmt: skip
            if why:
                reason = f"{reason}; {why}"
            self._event(imp, line, pc, False, reason, self._near(bib))
            if not self.from_memory:
                self._orphans.append((pc, k, t, imp.channel, bib, line, imp.tod_us, imp.flag))
                del self._orphans[:-MAX_ORPHANS]
            return done
        d = chosen
        self._join(d, pc, k, t, imp.channel)
        self._move_clock(t)
        # (the events list says where the memory's times begin, as the row's flags do)
        self._event(imp, line, pc, True, joined, d.number)
        _flag_damaged(d, imp, line)
        if k == len(self.photocells) - 1:
            self.open.remove(d)
            # a descent recovered without its start is short of the first photocell
            d.status = "complete" if d.photocells[0] == self.photocells[0] else "incomplete"
            self._done(d)
            done.append(d)
        done += self._expire(t)
        return done

    def _join(self, d: TimedDescent, pc: str, k: int, t: int, ch: str) -> None:
        """Photocell ``pc`` (index ``k``) at ``t`` on channel ``ch`` taken into descent ``d``:
        the photocells it skipped flagged and listed missing, the time kept against repeats.
        One method for a live impulse joining its descent (:meth:`_accept`) and a live one
        taken into a descent begun in the timer's memory (:meth:`_adopt`), which each had it
        line for line: a descent's missed photocells must read the same either way."""
        skipped = self.photocells[self.order[d.photocells[-1]] + 1 : k]
        if skipped:
            d.flags.append(f"missed {', '.join(skipped)}")
            d.missing += skipped
        d.photocells.append(pc)
        d.times_us.append(t)
        d.channels.append(ch)
        self._keep(ch, t)

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
            d.flags.append(_live_then_memory(last, pc))
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
        flag = _live_then_memory(d.photocells[-1], pc)
        d.flags.append(flag)
        return flag

    def _near(self, bib: str) -> int | None:
        """The descent an impulse was nearest to joining, for the events list."""
        for d in reversed(self.open):
            if not bib or d.bib == bib:
                return d.number
        return None

    def _why_not(self, d: TimedDescent, pc: str, k: int, t: int, by_order: bool) -> str | None:
        """Why descent ``d`` cannot take an impulse at photocell ``pc`` at ``t`` (None: it can)."""
        j = self.order[d.photocells[-1]]
        last = d.times_us[-1]
        if k < j:
            return f"out of order: {pc} after {d.photocells[-1]}"
        if k == j:
            return f"second impulse at {pc}, {(t - last) / 1e6:.3f} s after the first"
        if t <= last:
            return f"out of order: {(last - t) / 1e6:.4f} s earlier than {d.photocells[-1]}"
        if t - last > self.timeout_us[j]:
            return f"no impulse for {(t - last) / 1e6:.1f} s after {d.photocells[-1]}"
        if self.positions is None:
            return None
        pos = self.positions
        v = (pos[k] - pos[j]) / ((t - last) / 1e6)
        if v > self.max_speed:
            return (f"implausible: {v:.1f} m/s from {d.photocells[-1]} "
                    f"(at most {self.max_speed:g} m/s)")  # fmt: skip
        if by_order and len(d.photocells) >= 2:
            i = self.order[d.photocells[-2]]
            dt = (last - d.times_us[-2]) / 1e6
            if dt > 0:
                v_before = (pos[j] - pos[i]) / dt
                if not v_before / SPEED_RATIO <= v <= v_before * SPEED_RATIO:
                    return (f"implausible: {v:.1f} m/s from {d.photocells[-1]} after "
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

    def _kept_before(self, channel: str, t: int) -> bool:
        """``t`` is among the channel's older kept times (sorted)."""
        old = self._seen_old.get(channel)
        if not old:
            return False
        i = bisect_left(old, t)
        return i < len(old) and old[i] == t

    def _settle_seen(self) -> None:
        """Move each channel's kept times older than the clock's jump window from its set to
        its sorted array, once the set holds SEEN_RECENT of them."""
        if self._clock is None:
            return
        before = self._clock - self.jump_us
        for ch, seen in self._seen.items():
            if len(seen) < SEEN_RECENT:
                continue
            # sorted once and cut where the window begins: in C, not two passes of Python
            # over the set (they were 0.2 µs of every kept impulse in a replay)
            ordered = sorted(seen)
            cut = bisect_left(ordered, before)
            if not cut:
                continue
            older = ordered[:cut]
            self._seen[ch] = set(ordered[cut:])
            old = self._seen_old.get(ch)
            if old is None:
                old = self._seen_old[ch] = array("q")
            if old and older[0] <= old[-1]:  # not after them all (rare): merged
                old = self._seen_old[ch] = array("q", sorted({*old, *older}))
            else:
                old.extend(older)
            self._old_max = max(self._old_max, old[-1])

    def _done(self, d: TimedDescent) -> None:
        self.finished.append(d)
        self._last_done = d
        self._settle_seen()
        if d.status == "complete":
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

    # -- edits

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
        bib = _bib(e) if self.mode != "order" else ""
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
            and (not bib or not _bib(held[0]) or _bib(held[0]) == bib)
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
        target = None
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
            target = d
            break
        if target is None:
            if k == 0:
                self.count += 1
                d = TimedDescent(self.count, [pc], [t], first_line=line, channels=[e.channel],
                                 bib=bib, day=e.day)  # fmt: skip
                d.flags.append(f"start {when} {e.kind} at the timer")
                self.open.append(d)
                self._event(e, line, pc, True, f"{e.kind}: {pc} {when} starts descent "
                            f"{d.number}", d.number)  # fmt: skip
                return []
            self._event(e, line, pc, False,
                        f"{e.kind}: no descent{' of bib ' + bib if bib else ''} to enter "
                        f"{pc} {when} into; nothing changed")  # fmt: skip
            return []
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


#: the serial port's messages in a few words: pyserial's sentences for an unplugged adapter
_SHORT_DETAILS = (
    ("device reports readiness to read but returned no data", "no data: unplugged or in use"),
    ("device disconnected or multiple access on port", "unplugged or in use"),
)
#: the most of a port's message a descent's flag carries
DETAIL_CHARS = 40


def short_detail(detail: str) -> str:
    """The port's message in at most :data:`DETAIL_CHARS` characters for a descent's flag:
    a known pyserial sentence in a few words, any other cut at its first parenthesis and, if
    still long, with an ellipsis."""
    text = " ".join(detail.split())
    for long, short in _SHORT_DETAILS:
        if long in text:
            return short
    head = text.split(" (", 1)[0].strip() or text
    return head if len(head) <= DETAIL_CHARS else head[: DETAIL_CHARS - 1].rstrip() + "…"
