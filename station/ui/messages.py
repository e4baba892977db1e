"""Messages from the acquisition threads to the UI: the UI changes only through these, and each
carries an immutable snapshot (:mod:`station.session.records`), never the day itself."""

from __future__ import annotations

from textual.app import App
from textual.message import Message

from station.report.text import summary
from station.session.acquisition import Listener
from station.session.analysis import DescentResult
from station.session.comparison import DayComparison
from station.session.records import LineCounts, Progress
from station.timing.assembly import ImpulseEvent


class ConnectionChanged(Message):
    """The timer connected, disconnected, or cannot be opened; a replay started; an error."""

    def __init__(self, state: str, detail: str = "") -> None:
        super().__init__()
        self.state = state
        self.detail = detail


class ImpulsesArrived(Message):
    """Impulses parsed from the latest chunk, with what became of each."""

    def __init__(self, events: tuple[ImpulseEvent, ...], counts: LineCounts) -> None:
        super().__init__()
        self.events = events
        self.counts = counts


class DescentProgress(Message):
    """The open descent (``progress.number`` None: none open), and what the next one gets."""

    def __init__(self, progress: Progress) -> None:
        super().__init__()
        self.progress = progress


class DescentFitted(Message):
    """A descent finished and was fitted (or refitted, or re-annotated)."""

    def __init__(self, result: DescentResult) -> None:
        super().__init__()
        self.result = result


class SourceEnded(Message):
    """A replay reached its end (live sources do not end)."""

    def __init__(self, summary: str) -> None:
        super().__init__()
        self.summary = summary


class ComparisonUpdated(Message):
    """The test-day comparison, recomputed after a descent or an annotation."""

    def __init__(self, comparison: DayComparison) -> None:
        super().__init__()
        self.comparison = comparison


class AcquisitionWarning(Message):
    """Something failed (a fit, the results CSV) and the acquisition went on."""

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text


class PostingListener(Listener):
    """The acquisition's listener for the UI: every report becomes a message to the app
    (``post_message`` is safe from any thread)."""

    live_view = True

    def __init__(self, app: App) -> None:
        self.app = app

    def connection(self, state: str, detail: str) -> None:
        self.app.post_message(ConnectionChanged(state, detail))

    def impulses(self, events: tuple[ImpulseEvent, ...], counts: LineCounts) -> None:
        self.app.post_message(ImpulsesArrived(events, counts))

    def progress(self, progress: Progress) -> None:
        self.app.post_message(DescentProgress(progress))

    def result(self, result: DescentResult) -> None:
        self.app.post_message(DescentFitted(result))

    def comparison(self, comparison: DayComparison) -> None:
        self.app.post_message(ComparisonUpdated(comparison))

    def warning(self, text: str) -> None:
        self.app.post_message(AcquisitionWarning(text))

    def ended(self, counts: LineCounts, results: tuple[DescentResult, ...]) -> None:
        self.app.post_message(SourceEnded(summary(counts, results)))
