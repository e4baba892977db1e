"""The device clock: the timer's times of day unwrapped across midnight on the clock of the
impulses kept, and the index of kept times by which a repeat from the timer's memory is known
(not doubled) all day."""

from __future__ import annotations

from array import array
from bisect import bisect_left

from station.timing.assembler_base import AssemblerBase
from station.timing.impulses import DAY_US, Impulse

HALF_DAY_US = DAY_US // 2
#: the host clock confirms a jump of the device clock within this (µs)
HOST_TOLERANCE_US = 30_000_000
#: kept times a channel holds in its set before the older ones move to its sorted array
#: (8 bytes a time, not ~70): a repeat of any kept impulse is found all day
SEEN_RECENT = 64


class DeviceClock(AssemblerBase):
    """The clock, the unwrap and the kept times of :class:`AssemblerBase`'s state."""

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
