"""A descent as the assembler builds it, and the record of what became of each impulse: the
values every part of the assembler (and the session that keeps a day's descents) shares."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

from station.timing.impulses import DAMAGED_FLAG, Edit, Impulse


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
#: the fields of a descent that are lists while the assembler may change them
_LISTS = ("photocells", "times_us", "flags", "missing", "channels")


def is_joined(d: TimedDescent) -> bool:
    """Whether ``d`` says it was joined (live crossings and the timer's memory in one)."""
    return any(f.startswith(JOINED) for f in d.flags)


def live_then_memory(last: str, pc: str) -> str:
    """The flag of a descent recorded live up to ``last`` and from the timer's memory on
    from ``pc``: one wording whether the memory reopened it or continued it."""
    return f"{JOINED}{last} recorded live, {pc} on from the timer's memory"


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


def flag_damaged(d: TimedDescent, imp: Impulse, line: int) -> None:
    """A kept impulse read from a line with a damaged flag byte: the descent says so."""
    if imp.flag == DAMAGED_FLAG:
        d.flags.append(f"line {line}: flag byte {imp.line[:1]!r} damaged, read as an impulse")


#: an event made without the NamedTuple's Python-level ``__new__`` (a plain tuple's cost, the
#: same record: a day's replay makes one per impulse)
new_event = tuple.__new__


def bib_of(imp: Impulse | Edit) -> str:
    """A valid bib: digits, not all zeros, not flagged ``?`` (time without valid number)."""
    if imp.flag == "?":
        return ""
    return imp.bib.strip().lstrip("0")


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
