"""Impulses -> descents: a pure state machine, no I/O and no clock of its own.

A descent starts with an impulse at the first photocell and ends at the last one. Or it ends when
the skier can no longer be on the run: ``timeout_s`` after the last impulse, or by default the
distance to the photocell after next at the slowest plausible speed. Then it is fitted with the
photocells it has and flagged. What happens in the field:

- double triggers (legs, poles) at one photocell within ``debounce_s`` collapse to the first;
- a missed photocell leaves a gap: the descent goes on and is flagged;
- a lone start impulse that nothing follows (someone walking through the beam) is *aborted*;
- the next start while a descent is open ends the open one;
- time of day wraps at midnight (ALGE and Microgate have no date);
- an impulse out of order (earlier photocell, or earlier time) is rejected with its reason;
- an impulse on a channel that is no photocell (keypad, unused input) is rejected as such.

Every impulse comes out once in ``events`` with whether it was kept and why not.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

from station.timing.impulses import DAY_US, Impulse

HALF_DAY_US = DAY_US // 2


@dataclass
class TimedDescent:
    """One skier's pass: the kept time at each photocell (µs, unwrapped across midnight)."""

    number: int
    photocells: list[str]  # the photocells with a time, in order down the run
    times_us: list[int]
    status: str = "open"  # complete | incomplete | aborted
    flags: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    first_line: int = 0

    @property
    def start_us(self) -> int:
        return self.times_us[0]


class ImpulseEvent(NamedTuple):
    """What became of one impulse."""

    line: int
    channel: str
    photocell: str | None
    tod_us: int
    flag: str
    kept: bool
    reason: str = ""
    descent: int | None = None


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
    ) -> None:
        self.order = {pc: i for i, pc in enumerate(photocells)}
        self.photocells = list(photocells)
        self.channels = dict(channels)
        self.debounce_us = round(debounce_s * 1e6)
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
        self.current: TimedDescent | None = None
        self.count = 0
        self.events: list[ImpulseEvent] = []
        self._day_offset = 0
        self._clock: int | None = None  # unwrapped time of the latest impulse

    # -- time

    @property
    def clock(self) -> int | None:
        """Device time of the latest accepted impulse (µs, unwrapped); None before the first."""
        return self._clock

    def unwrap(self, imp: Impulse) -> int:
        """Time of day -> a monotone device time in µs (midnight wraps forward)."""
        if imp.day is not None:
            return imp.day * DAY_US + imp.tod_us
        t = self._day_offset * DAY_US + imp.tod_us
        if self._clock is not None and t < self._clock - HALF_DAY_US:
            self._day_offset += 1
            t += DAY_US
        return t

    # -- impulses

    def _event(self, imp: Impulse, line: int, pc, kept: bool, reason: str = "", descent=None):
        self.events.append(
            ImpulseEvent(line, imp.channel, pc, imp.tod_us, imp.flag, kept, reason, descent)
        )

    def feed(self, imp: Impulse, line: int = 0) -> list[TimedDescent]:
        """One impulse in; the descents it finished out."""
        done: list[TimedDescent] = []
        pc = self.channels.get(imp.channel)
        if pc is None:
            self._event(imp, line, None, False, f"channel {imp.channel} is not a photocell")
            return done
        t = self.unwrap(imp)
        if self._clock is not None and t < self._clock:
            back = (self._clock - t) / 1e6
            self._event(
                imp,
                line,
                pc,
                False,
                f"out of order: {back:.4f} s earlier than the previous impulse",
            )
            return done
        self._clock = t
        k = self.order[pc]
        cur = self.current
        if cur is not None:
            j = self.order[cur.photocells[-1]]
            last = cur.times_us[-1]
            if k == j and t - last <= self.debounce_us:
                cur.flags.append(f"double trigger at {pc} collapsed (+{(t - last) / 1e6:.3f} s)")
                self._event(
                    imp, line, pc, False, "double trigger within the debounce window", cur.number
                )
                return done
            if t - last > self.timeout_us[j]:
                done += self._finish(
                    f"no impulse for {(t - last) / 1e6:.1f} s after {cur.photocells[-1]}"
                )
                cur = None
            elif k == 0:
                done += self._finish(f"ended by the next start at {pc}")
                cur = None
        if cur is None:
            if k != 0:
                self._event(imp, line, pc, False, f"{pc} without a start at {self.photocells[0]}")
                return done
            self.count += 1
            self.current = TimedDescent(self.count, [pc], [t], first_line=line)
            self._event(imp, line, pc, True, "", self.count)
            return done
        if k < j:
            self._event(
                imp, line, pc, False, f"out of order: {pc} after {cur.photocells[-1]}", cur.number
            )
            return done
        if k == j:
            self._event(
                imp, line, pc, False,
                f"second impulse at {pc}, {(t - last) / 1e6:.3f} s after the first", cur.number,
            )  # fmt: skip
            return done
        skipped = self.photocells[j + 1 : k]
        if skipped:
            cur.flags.append(f"missed {', '.join(skipped)}")
            cur.missing += skipped
        cur.photocells.append(pc)
        cur.times_us.append(t)
        self._event(imp, line, pc, True, "", cur.number)
        if k == len(self.photocells) - 1:
            cur.status = "complete"
            done.append(cur)
            self.current = None
        return done

    def tick(self, now_us: int) -> list[TimedDescent]:
        """Device time now (estimated from the host clock): end a descent that timed out."""
        cur = self.current
        if cur is None:
            return []
        j = self.order[cur.photocells[-1]]
        if now_us - cur.times_us[-1] > self.timeout_us[j]:
            waited = (now_us - cur.times_us[-1]) / 1e6
            return self._finish(f"no impulse for {waited:.1f} s after {cur.photocells[-1]}")
        return []

    def close(self) -> list[TimedDescent]:
        """End of the capture: an open descent ends here."""
        if self.current is None:
            return []
        return self._finish("the recording ended")

    def _finish(self, why: str) -> list[TimedDescent]:
        cur = self.current
        assert cur is not None
        self.current = None
        if len(cur.photocells) == 1:
            cur.status = "aborted"
            cur.flags.append(f"lone start impulse, {why}")
        else:
            cur.status = "incomplete"
            last = self.order[cur.photocells[-1]]
            tail = self.photocells[last + 1 :]
            cur.missing += tail
            cur.flags.append(f"{why}; missing {', '.join(tail)}")
        return [cur]
