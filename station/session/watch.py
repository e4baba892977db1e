"""A config that does not match the timer, said while the timer is heard: impulses on channels
the config does not map to a photocell, and lines that do not parse as the config's protocol,
give one warning within seconds (and again every minute while it lasts), naming what was
heard and what the config expects. Without it a wrong config records nothing, silently, for
as long as the day lasts.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Mapping

from station.session.processor import Processor
from station.session.records import LineCounts
from station.timing.assembly import ImpulseEvent
from station.timing.impulses import Edit, Impulse
from station.timing.wireformats import PARSERS, make_parser

#: a warning that still holds is said again after this long (s)
AGAIN_S = 60.0
#: lines that do not parse, with no impulse parsed, before the protocol is called wrong
UNPARSED_RUN = 4
#: impulses on channels the config does not map before they are named
UNMAPPED_SEEN = 2
#: the latest unparsed lines tried with the other protocols' parsers
SAMPLE = 20


class ConfigWatch:
    """Fed what each chunk did (:meth:`note`); returns a warning when it is due."""

    def __init__(self, protocol: str, channels: Mapping[str, str]) -> None:
        self.protocol = protocol
        self.channels = dict(channels)
        self.unmapped: Counter[str] = Counter()
        self.unparsed: list[str] = []  # the latest lines that did not parse
        self._said: dict[str, float] = {}  # what was said last, by kind, and when
        self._unparsed_seen = 0  # the processor's unparsed lines looked at

    def look(self, proc: Processor, first_event: int, t: float) -> list[str]:
        """:meth:`note` of what the processor did since its event ``first_event``."""
        texts = [text for _line, _why, text in proc.unparsed[self._unparsed_seen :]]
        self._unparsed_seen = len(proc.unparsed)
        return self.note(proc.events[first_event:], proc.line_counts(), texts, t)

    def note(
        self, events: Iterable[ImpulseEvent], counts: LineCounts, unparsed: Iterable[str], t: float
    ) -> list[str]:
        """The impulses of the latest chunk, the line counts so far and the texts of the lines
        that did not parse; returns the warnings due at time ``t`` (s)."""
        for e in events:
            if e.photocell is None and e.channel not in self.channels:
                self.unmapped[e.channel] += 1
        self.unparsed = [*self.unparsed, *unparsed][-SAMPLE:]
        out = []
        for kind, text in (("channels", self._channels()), ("protocol", self._protocol(counts))):
            said = self._said.get(kind)
            if text and (said is None or t - said >= AGAIN_S):
                self._said[kind] = t
                out.append(text)
        return out

    def _channels(self) -> str:
        if sum(self.unmapped.values()) < UNMAPPED_SEEN:
            return ""
        heard = ", ".join(f"{ch} ({n}×)" for ch, n in sorted(self.unmapped.items()))
        expected = ", ".join(self.channels) or "none"
        return (f"the timer sends impulses on channel {heard}, which the config does not map "
                f"to a photocell (photocells: maps {expected}): those impulses start and time "
                "no descent; correct photocells: in the config")  # fmt: skip

    def _protocol(self, counts: LineCounts) -> str:
        if counts.unparsed < UNPARSED_RUN or counts.impulses or counts.edits:
            return ""
        others = sorted(
            (sum(_parses(p, line) for line in self.unparsed), p)
            for p in PARSERS
            if p != self.protocol
        )
        best = others[-1] if others else (0, "")
        hint = "; check the timer's output format and serial: protocol:"
        if best[0]:
            hint = f"; they parse as {best[1]}: set serial: protocol: {best[1]} in the config"
        return (f"{counts.unparsed} lines from the timer, none of them an impulse as "
                f"{self.protocol} sends it{hint}")  # fmt: skip


def _parses(protocol: str, line: str) -> bool:
    """Whether ``line`` is an impulse or an edit in ``protocol``."""
    try:
        return isinstance(make_parser(protocol).parse(line), Impulse | Edit)
    except Exception:  # noqa: BLE001 - a guess at another protocol never fails the watch
        return False
