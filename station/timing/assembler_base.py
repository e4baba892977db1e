"""The assembler's state and configuration, in one place for the parts that read and change
them (the device clock, pairing, recovery of damaged lines, the timer's memory, edits): each
part is a class of its own module, and :class:`station.timing.assembly.DescentAssembler` is
all of them over this state."""

from __future__ import annotations

from array import array
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING

from station.timing.descent import ImpulseEvent, TimedDescent, new_event
from station.timing.impulses import Edit, Impulse

PAIRINGS = ("auto", "bib", "order")


@dataclass
class Damage:
    """A line the caller could not read: where it came in the device's time."""

    line: int
    after_us: int | None  # the device clock when it came: its time was not earlier
    before_us: int | None = None  # the first time kept after it: its time was not later


def wired_run(
    photocells: list[str], channels: dict[str, str], positions_m: list[float] | None
) -> tuple[list[str], list[float] | None]:
    """The photocells wired to a channel (only they can have times: a descent ends at the last
    of them, and its time-outs run to the wired photocell after next), and their positions."""
    wired = set(channels.values())
    keep = [i for i, pc in enumerate(photocells) if pc in wired] or list(range(len(photocells)))
    return [photocells[i] for i in keep], (
        [positions_m[i] for i in keep] if positions_m is not None else None
    )


def timeouts_us(n: int, timeout_s: float | None, positions_m: list[float] | None,
                min_speed_ms: float) -> list[int]:  # fmt: skip
    """The time-out after each photocell (µs): ``timeout_s``, or the time to the photocell
    after next (one may be missed) at ``min_speed_ms``, or a minute without positions."""
    if timeout_s is not None:
        return [round(timeout_s * 1e6)] * n
    if positions_m is not None:
        return [
            round((positions_m[min(j + 2, n - 1)] - positions_m[j]) / min_speed_ms * 1e6)
            for j in range(n)
        ]
    return [60_000_000] * n


class AssemblerBase:
    """The configuration (photocells, channels, the plausible speeds and time-outs) and the
    state of a day's assembly."""

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
        photocells, positions_m = wired_run(photocells, channels, positions_m)
        self.order = {pc: i for i, pc in enumerate(photocells)}
        self.photocells = list(photocells)
        self.channels = dict(channels)
        self.debounce_us = round(debounce_s * 1e6)
        self.positions = list(positions_m) if positions_m is not None else None
        self.min_speed = min_speed_ms
        self.max_speed = max_speed_ms
        n = len(photocells)
        self.timeout_us = timeouts_us(n, timeout_s, positions_m, min_speed_ms)
        self.jump_us = (
            round(jump_s * 1e6) if jump_s is not None else max(60_000_000, *self.timeout_us)
        )
        self.pairing = pairing
        self.mode: str | None = None if pairing == "auto" else pairing
        #: channel -> (the config's string for it, photocell, its index, the distance from the
        #: photocell before, m): what an impulse's channel tells, in one look-up
        self._fast_channels: dict[str, tuple[str, str, int, float | None]] = {
            ch: (ch, pc, k, None if k == 0 or self.positions is None
                 else self.positions[k] - self.positions[k - 1])
            for ch, pc in self.channels.items()
            if (k := self.order.get(pc)) is not None
        }  # fmt: skip
        self._last_k = n - 1
        self._init_state()

    def _init_state(self) -> None:
        """A day not begun: no descent, no clock, nothing kept."""
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
        self._damaged: list[Damage] = []  # unread lines that may have been a start
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

    def _event(self, imp: Impulse | Edit, line: int, pc: str | None, kept: bool, reason: str = "",
               descent: int | None = None) -> None:  # fmt: skip
        self.events.append(
            new_event(
                ImpulseEvent, (line, imp.channel, pc, imp.tod_us, imp.flag, kept, reason, descent)
            )
        )

    if TYPE_CHECKING:  # the parts' methods the others call (one class at run time)

        def feed(
            self, imp: Impulse, line: int = 0, now_us: int | None = None
        ) -> list[TimedDescent]: ...
        def _time(self, tod_us: int, day: int | None) -> int: ...
        def _move_clock(self, t: int) -> None: ...
        def _keep(self, channel: str, t: int) -> None: ...
        def _settle_seen(self) -> None: ...
        def _mid(self, k: int) -> float | None: ...
        def _why_not(
            self, d: TimedDescent, pc: str, k: int, t: int, by_order: bool
        ) -> str | None: ...
        def _score(self, d: TimedDescent, k: int, t: int) -> tuple[float, int]: ...
        def _join(self, d: TimedDescent, pc: str, k: int, t: int, ch: str) -> None: ...
        def _done(self, d: TimedDescent) -> None: ...
        def _take_held(self) -> list[TimedDescent]: ...
