"""Messages from the worker threads to the UI: the UI changes only through these."""

from __future__ import annotations

from textual.message import Message

from station.session.analysis import DescentResult
from station.timing.assembly import ImpulseEvent


class ConnectionChanged(Message):
    """The timer connected, disconnected, or cannot be opened."""

    def __init__(self, state: str, detail: str = "") -> None:
        super().__init__()
        self.state = state
        self.detail = detail


class ImpulsesArrived(Message):
    """Impulses parsed from the latest chunk, with what became of each."""

    def __init__(self, events: list[ImpulseEvent], counts: dict[str, int]) -> None:
        super().__init__()
        self.events = events
        self.counts = counts


class DescentProgress(Message):
    """The open descent: its number and the photocells passed so far (None: none open)."""

    def __init__(self, number: int | None, passed: list[str], times_us: list[int]) -> None:
        super().__init__()
        self.number = number
        self.passed = passed
        self.times_us = times_us


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

    def __init__(self, text: str) -> None:
        super().__init__()
        self.text = text
