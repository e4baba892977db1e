"""Annotations entered while a day is acquired: the recorder's own (metadata, marks, refits)
and those another process appends to the session (``station annotate`` while this records),
applied to the day in the order of the annotations file, as a replay applies them.

Every writer appends to annotations.jsonl only under its flock
(:func:`station.session.folder.annotations_locked`). The fits the records call for go to the
fit worker, which sees by then every fit already under way; it looks for others' records when
idle, and :meth:`~station.session.acquisition.Acquisition.close` takes up the last of them.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from station.session import folder as sessions
from station.session.day import Day, Effect
from station.session.jobs import Annotate, Job
from station.session.listener import Listener
from station.session.records import Annotation, Metadata, MetadataAnnotation, ModelChange

#: how long the recorder waits for another writer of the annotations file (it appends one
#: record) before it appends its own without the lock
ANNOTATIONS_WAIT_S = 2.0


class AnnotationIntake:
    """The acquisition's side of the annotations file (a base of
    :class:`~station.session.acquisition.Acquisition`, which owns the state named here)."""

    day: Day
    lock: threading.Lock
    listener: Listener
    session_dir: str | None
    _jobs: queue.Queue[object]
    _ann_offset: int  # bytes of annotations.jsonl taken up (own and others' records)
    _own_lines: list[str]  # own records appended, not yet read back
    _fit_from: int  # the highest descent whose fit has begun (under the lock)
    _last_poll: float
    _closing: bool

    def _submit(self, job: Job) -> None:
        raise NotImplementedError

    def _submit_all(self, jobs: Iterable[Job]) -> None:
        raise NotImplementedError

    def _tell(self, fn: Callable[..., None], *args: Any) -> None:
        raise NotImplementedError

    def _not_as_replayed(self, why: str) -> None:
        raise NotImplementedError

    def add_metadata(self, values: Mapping[str, Any], from_descent: int | None = None) -> int:
        """Metadata for the next descent on (or from ``from_descent``), stored and applied at
        once, so the descent it is for sees it; returns the number it applies from."""
        with self.lock:
            start, jobs = self._add_metadata_locked(values, from_descent)
            progress = self.day.progress()
        self._submit_all(jobs)
        if self.listener.live_view:
            self._tell(self.listener.progress, progress)
        return start

    def _add_metadata_locked(
        self, values: Mapping[str, Any], from_descent: int | None
    ) -> tuple[int, list[Job]]:
        start = from_descent if from_descent is not None else self.day.next_number()
        a = MetadataAnnotation(Metadata.from_values(values), from_descent=start, t=time.time())
        if self.session_dir is None:
            self.day.annotate(a)
            return start, []
        return start, self._record_locked(a)

    def annotate(self, a: Annotation) -> None:
        """An invalid mark, a valid mark or a refit: stored now, fitted again by the fit worker
        after the descents already queued."""
        if self.session_dir is None:
            self._submit(Annotate(a))  # applied by the worker, in its turn
            return
        with self.lock:
            jobs = self._record_locked(a)
        self._submit_all(jobs)

    def _record_locked(self, own: Annotation) -> list[Job]:
        """With the lock held: store ``own`` after what others appended before it, and apply
        both in the file's order. A writer holding the file longer than ANNOTATIONS_WAIT_S
        does not stop the day: the record is appended without the file lock then."""
        assert self.session_dir is not None
        with sessions.annotations_locked(self.session_dir, ANNOTATIONS_WAIT_S):
            return self._take_up_locked(own)

    def _take_up_locked(self, own: Annotation | None = None) -> list[Job]:
        """With the lock and the annotations file held: the records others appended since the
        last look, then ``own``, applied to the day; the jobs that fit again and show them."""
        assert self.session_dir is not None
        records, self._ann_offset = sessions.read_annotations_after(
            self.session_dir, self._ann_offset
        )
        taken: list[Annotation] = []
        for rec in records:
            if rec.line in self._own_lines:  # ours, applied when it was written
                self._own_lines.remove(rec.line)
            elif rec.problem:
                self._not_as_replayed("a record of the annotations file was passed over")
                self._tell(self.listener.warning, f"{sessions.ANNOTATIONS}: {rec.problem}; "
                           "passed over")  # fmt: skip
            elif rec.annotation is not None:
                taken.append(rec.annotation)
        if own is not None:
            self._own_lines.append(sessions.append_annotation(self.session_dir, own))
            taken.append(own)
        jobs: list[Job] = []
        for a in taken:
            if (
                isinstance(a, MetadataAnnotation)
                and a.descents is None
                and self._fit_from >= (a.from_descent or 0)
            ):
                # a replay applies it to those fitted already (or being fitted); the
                # recording does not
                self._not_as_replayed("metadata from a descent already fitted on")
            self.day.annotate(a)
            if not (isinstance(a, MetadataAnnotation) and a.descents is None):
                jobs.append(Annotate(a, applied=True))  # a change from N on: nothing to refit
        return jobs

    def _poll_annotations(self) -> None:
        """The worker, idle: take up what another process appended (without waiting for the
        file: a writer holding it is asked again at the next look)."""
        self._last_poll = time.monotonic()
        if self.session_dir is None or self._closing:
            return
        try:
            grown = os.path.getsize(os.path.join(self.session_dir, sessions.ANNOTATIONS))
        except OSError:
            return
        if grown <= self._ann_offset:
            return
        jobs: list[Job] = []
        with self.lock, sessions.annotations_locked(self.session_dir, 0.0) as held:
            if held is not False:
                jobs = self._take_up_locked()
            progress = self.day.progress()
        for job in jobs:
            self._jobs.put(job)  # this worker runs them next, in order
        if jobs and self.listener.live_view:
            self._tell(self.listener.progress, progress)


def effect_now(day: Day, a: Annotation) -> Effect:
    """What an annotation the day already has calls for, now: the descents it concerns that
    are fitted by now (one fitted meanwhile was fitted before it, or with it: fitted again)."""
    if isinstance(a, MetadataAnnotation):
        numbers = sorted(a.descents or ())
        return Effect(refit=tuple(n for n in numbers if n in day.results))
    if a.descent not in day.results:
        return Effect()
    if isinstance(a, ModelChange):
        return Effect(refit=(a.descent,))
    return Effect(changed=(a.descent,))
