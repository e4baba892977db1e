"""What the acquisition's fit worker is given to do, in order: fit a descent, apply an
annotation and fit again what it concerns, say that the source ended, write the results CSV
(:mod:`station.session.acquisition`)."""

from __future__ import annotations

from dataclasses import dataclass

from station.session.records import Annotation, DescentTimes


@dataclass(frozen=True)
class Fit:
    descent: DescentTimes


@dataclass(frozen=True)
class Annotate:
    annotation: Annotation
    #: already applied to the day (a session's annotations are, in the order of its file):
    #: the job only fits again and shows what it concerns
    applied: bool = False


@dataclass(frozen=True)
class End:
    """The source ended: tell the listener once every descent before it is fitted."""


@dataclass(frozen=True)
class WriteResults:
    """Write the session's results CSV (the empty one at the start: on the worker, so the
    reader opens the port without waiting for the CSV writer to load)."""


#: ends the worker
STOP = object()


Job = Fit | Annotate | End | WriteResults
