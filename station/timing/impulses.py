"""What a timer line means: an impulse, an edit of an earlier one, or a line to pass over.

Times of day are integer microseconds since midnight, never floats: every device resolution
(ALGE 1e-4 s, TAG 1e-5 s, Microgate 1e-3 s, keypad 1e-2 s) is exact in them, and sums and
differences stay exact. ``resolution_us`` keeps what the device actually measured. The
records are NamedTuples because a day's replay creates hundreds of thousands of them: they cost
a third of a frozen dataclass.
"""

from __future__ import annotations

from typing import NamedTuple

DAY_US = 86_400_000_000
#: the flag of an impulse read from a line whose flag byte was damaged (an unknown flag, but a
#: channel, time and number that read): kept, and its descent says so
DAMAGED_FLAG = "damaged"


class Impulse(NamedTuple):
    """A beam break (or keypad press) as the timer reported it."""

    channel: str  # as the device names it: "C0", "C1", "M" (keypad), "1", "M1", "000"
    tod_us: int  # time of day, µs since midnight
    resolution_us: int
    flag: str  # "" normal, "?" no bib; device-specific otherwise
    bib: str
    day: int | None = None  # days since 2000-01-01 where the device says (TAG)
    line: str = ""


class Edit(NamedTuple):
    """A line that repeats, clears or edits an earlier impulse: never a new impulse."""

    kind: str  # "cleared", "edited", "disqualified", "removed", …
    channel: str
    tod_us: int
    flag: str
    bib: str
    line: str = ""
    day: int | None = None  # days since 2000-01-01 where the device says (TAG)


#: the :attr:`Edit.kind` of a line that repeats an impulse from the timer's memory (ALGE
#: ``m``): an impulse, not an edit (the assembler keeps it unless it is already; the counts
#: call it an impulse)
MEMORY_REPEAT = "repeated from memory"


class Skip(NamedTuple):
    """A line the timer sends that is not an impulse (status, running time, print-out)."""

    reason: str
    line: str = ""


class Unparsed(NamedTuple):
    """A line that parses as nothing: counted, kept in the raw log, never fatal."""

    reason: str
    line: str = ""


Parsed = Impulse | Edit | Skip | Unparsed


def format_tod(tod_us: int, decimals: int = 4) -> str:
    """µs since midnight -> ``HH:MM:SS.ffff``."""
    tod_us %= DAY_US
    s, us = divmod(tod_us, 1_000_000)
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    frac = f"{us:06d}"[:decimals]
    return f"{h:02d}:{m:02d}:{sec:02d}" + (f".{frac}" if decimals else "")
