"""What the engineer enters in the UI: run metadata, invalid and valid marks, a refit with the
other model, an export of the results; in a replay, kept and saved in the session at the end
(a base of :class:`~station.ui.app.StationApp`, which owns the state named here)."""

from __future__ import annotations

import os
import time
from dataclasses import replace
from typing import Any

from textual.app import App

from station.report.text import count
from station.session.acquisition import Acquisition
from station.session.analysis import DescentResult
from station.session.config import StationConfig
from station.session.folder import RESULTS
from station.session.recorded_session import RecordedSession
from station.session.records import (
    Annotation,
    FitModel,
    InvalidMark,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    Progress,
    ValidMark,
)
from station.ui.screens import HelpScreen, MetadataScreen, ReasonScreen


class EngineerActions(App):
    """The keys ``m``, ``i``, ``v``, ``e`` and ``?``."""

    acq: Acquisition | None
    config: StationConfig
    mode: str
    progress: Progress | None
    recorded: RecordedSession | None
    results: dict[int, DescentResult]
    kept: list[Annotation]
    metadata_from: int | None
    session_dir: str | None
    source: str | None

    def _cursor_number(self) -> int | None:
        raise NotImplementedError

    def _selected(self) -> int | None:
        """The descent ``i`` and ``v`` act on: the selected row, which the panel shows."""
        n = self._cursor_number()
        if n is None:
            self.notify("no descent yet", severity="warning")
        return n

    def action_help(self) -> None:
        self.push_screen(HelpScreen())

    def action_metadata(self) -> None:
        p = self.progress
        nxt = p.next_number if p is not None else 1
        current = p.next_metadata.values() if p is not None else {}

        def done(values: dict[str, Any] | None) -> None:
            if values is None or self.acq is None:
                return
            if not values:  # saved as it was: nothing to record, nothing to apply
                self.notify("metadata unchanged: nothing saved")
                return
            stopped = ""
            if "ski" in values and self.acq.ski_rotation:
                # the engineer took over the skis: the demo's rotation would overwrite the
                # typed ski when the next descent starts
                self.acq.ski_rotation = ()
                stopped = "; the demo's rotation of skis stops"
            start = self.metadata_from = self.acq.add_metadata(values)
            a = MetadataAnnotation(Metadata.from_values(values), from_descent=start, t=time.time())
            self.notify(f"metadata applies from descent {start} on{self._keep(a)}{stopped}")

        self.push_screen(MetadataScreen(current, nxt), done)

    def action_invalid(self) -> None:
        n = self._selected()
        if n is None or self.acq is None:
            return
        res = self.results.get(n)
        if res is not None and res.row.invalid:
            self.acq.annotate(ValidMark(n))
            self.notify(f"descent {n} valid again{self._keep(ValidMark(n))}")
            return

        def done(reason: str | None) -> None:
            if reason is not None and self.acq is not None:
                self.acq.annotate(InvalidMark(n, reason))
                kept = self._keep(InvalidMark(n, reason))
                self.notify(f"descent {n} marked invalid: {reason}{kept}")

        self.push_screen(ReasonScreen(n), done)

    def action_refit(self) -> None:
        n = self._selected()
        if n is None or self.acq is None:
            return
        res = self.results.get(n)
        current = res.row.model if res is not None else FitModel(self.config.model)
        model = FitModel.CONSTANT if current == FitModel.VELOCITY else FitModel.VELOCITY
        self.acq.annotate(ModelChange(n, model))
        kept = self._keep(ModelChange(n, model))
        self.notify(f"refitting descent {n} with the {model} model{kept}")

    def _keep(self, a: Annotation) -> str:
        """A recording saves what the engineer enters as it goes; a replay records nothing, so
        what is entered while replaying a session is kept and saved in that session when the
        UI ends. A plain capture has no session to save it in: said at once, not lost silently.
        Returns what the notification adds."""
        if self.mode != "replay":
            return ""
        if self.recorded is not None:
            self.kept.append(a if a.t is not None else replace(a, t=time.time()))
            return " (saved in the session when you quit)"
        return " (this replay only: a capture file has no session; e exports the results)"

    def action_export(self) -> None:
        if self.acq is None:
            return
        if self.session_dir is not None:
            path = os.path.join(self.session_dir, RESULTS)
        else:
            base = os.path.splitext(os.path.basename(os.path.normpath(self.source or "replay")))[0]
            path = os.path.abspath(f"{base}-results.csv")
        try:
            written = self.acq.write_csv(path)
        except OSError as exc:
            self.notify(f"{path} not written: {exc}", severity="error")
            return
        # the rows written, not the rows shown: a descent whose fit is still on its way to
        # the table is in the file too
        self.notify(f"{count(written, 'descent')} exported to {path}")
