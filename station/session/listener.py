"""What an acquisition tells the outside world (:mod:`station.session.acquisition`): the views
(the console, the UI) subclass :class:`Listener`."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

from station.session.analysis import DescentResult
from station.session.records import LineCounts, Progress

if TYPE_CHECKING:
    from station.session.comparison import DayComparison
    from station.timing.assembly import ImpulseEvent


class Listener:
    """What an acquisition tells the outside world. Called from the reader and the fit worker
    threads, always with immutable records; the defaults do nothing, but for warnings, which
    go to stderr: a failure is never passed over in silence."""

    #: wants every impulse and the open descent's progress (the UI); a headless run does not
    live_view = False

    def connection(self, state: str, detail: str) -> None:
        """The timer connected, disconnected, cannot be opened; a replay started; an error."""

    def impulses(self, events: tuple[ImpulseEvent, ...], counts: LineCounts) -> None:
        """Impulses parsed from the latest chunk, with what became of each."""

    def progress(self, progress: Progress) -> None:
        """The open descent, and the number and metadata the next one will get."""

    def result(self, result: DescentResult) -> None:
        """A descent was fitted, fitted again, or marked."""

    def comparison(self, day: DayComparison) -> None:
        """The day's comparison of items, recomputed (while shown, and when the source
        ended)."""

    def warning(self, text: str) -> None:
        """Something failed and the acquisition went on."""
        print(f"warning: {text}", file=sys.stderr, flush=True)

    def ended(self, counts: LineCounts, results: tuple[DescentResult, ...]) -> None:
        """A replay reached its end and every descent is fitted: the lines read and the
        descents as the results show them (the summary is the listener's to word)."""


class QuietListener(Listener):
    """Says nothing, warnings neither: a replay whose caller reports only its results (export,
    annotate, compare, report), where a line per descent or a repeated site warning would
    bury the one answer asked for."""

    def warning(self, text: str) -> None:
        pass
