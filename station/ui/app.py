"""The trackside UI: live from a timer, a demo with the simulated timer, or a replay.

Wiring only: the acquisition loop (:mod:`station.session.acquisition`) reads the timer or the
replay, writes the raw log first, fits finished descents and writes the results CSV in threads
of its own; it reports to the UI through messages (:mod:`station.ui.messages`) that carry
immutable snapshots. The UI thread never parses, fits, reads the port or touches the day: what
it shows is what the messages brought, and what the engineer enters goes to the acquisition.
"""

from __future__ import annotations

import datetime as dt
import os
import time
from dataclasses import replace
from typing import Any

from textual.binding import Binding
from textual.widgets import DataTable, RichLog, Static

from station import runtime
from station.report.comparison_text import comparison_view, headline
from station.session.acquisition import Acquisition
from station.session.analysis import DescentResult
from station.session.comparison import DayComparison
from station.session.config import StationConfig
from station.session.folder import is_session
from station.session.recorded_session import RecordedSession
from station.session.records import (
    Annotation,
    LineCounts,
    Progress,
)
from station.timing.impulses import format_tod
from station.ui.actions import EngineerActions
from station.ui.cells import Column, cell, justify, panel_text, table_columns
from station.ui.messages import (
    AcquisitionWarning,
    ComparisonUpdated,
    ConnectionChanged,
    DescentFitted,
    DescentProgress,
    ImpulsesArrived,
    PostingListener,
    SourceEnded,
)
from station.ui.plots import residual_text, speed_text
from station.ui.screens import (
    ComparisonScreen,
    MainScreen,
    MetadataScreen,
)
from station.ui.simulator import SimulatedTimer, SimulatorError

#: below this width the log of impulses is hidden: the result panel beside its 46 columns
#: needs 84 for μ and CdA with their intervals on one line (at 110 it cut CdA's interval)
NARROW = 130
#: a full garbage collection is looked for COLLECT_AFTER_S after each fit (on the screen by
#: then: with a dialog open it takes two refreshes, and a callback after the first ran before
#: the fit's frame; the next descent's end is furthest away then) and, every COLLECT_EVERY_S,
#: when no fit came for QUIET_S and no descent is open (s): a collection at any other moment
#: may fall on the next fit's path
COLLECT_AFTER_S = 0.2
#: what arrives while a descent's fit is due (its last impulse in the log, the counts, the
#: progress) is drawn with the fit, in one frame, or after this long if no fit comes (s)
HOLD_S = 0.3
COLLECT_EVERY_S = 5.0
QUIET_S = 30.0


class StationApp(EngineerActions):
    """One session at the trackside."""

    CSS_PATH = "station.tcss"
    TITLE = "station"
    BINDINGS = [
        Binding("m", "metadata", "Metadata"),
        Binding("i", "invalid", "Invalid"),
        Binding("v", "refit", "Velocity model"),  # "v Refit v" read as a stutter
        Binding("e", "export", "Export"),
        Binding("c", "compare", "Compare"),
        Binding("question_mark,f1", "help", "Help", key_display="?"),
        Binding("q", "quit", "Quit"),
    ]

    def __init__(
        self,
        config: StationConfig,
        *,
        mode: str = "live",
        source: str | None = None,
        session_dir: str | None = None,
        speed: float | None = None,
        date: dt.date | None = None,
        sim_command: list[str] | None = None,
        demo_skis: list[str] | None = None,
        recorded: RecordedSession | None = None,
    ) -> None:
        super().__init__()
        self.mode = mode
        self.source = source
        #: the session replayed (``replay --ui SESSION``): it replays itself, and what is
        #: entered is saved in it at the end; None for a plain capture, live and demo
        if recorded is None and mode == "replay" and source and is_session(source):
            recorded = RecordedSession(source, config)
        self.recorded = recorded
        self.session_dir = session_dir
        self.speed = speed
        self.date = date
        self.sim = SimulatedTimer(sim_command) if sim_command else None
        self.demo_skis = demo_skis or []
        self.config = config
        self.acq: Acquisition | None = None
        self.collector = runtime.IdleCollector()
        self._fitted_at = 0.0  # time.monotonic() of the latest fit
        #: drawn with the fit that is due (HOLD_S): the log's lines, the progress's text
        self._held_log: list[str] = []
        self._held_progress: str | None = None
        self._hold_timer: Any = None  # set while lines are held (see _holding)
        self.photocell_ids: tuple[str, ...] = ()
        # what the messages brought: the UI's own snapshots of the day
        self.results: dict[int, DescentResult] = {}
        self.progress: Progress | None = None
        self.counts = LineCounts()
        self.metadata_from: int | None = None  # where the latest metadata entered applies from
        #: marks and metadata entered while replaying: a replay records nothing, so they are
        #: kept here and saved in the replayed session when the UI ends (station annotate's way)
        self.kept: list[Annotation] = []
        self.latest: int | None = None
        self.shown: int | None = None  # the descent the result panel shows: the selected row
        self.columns: list[Column] = []
        self.plot_rows = 6
        self._plotted: DescentResult | None = None
        self._resid_width = 0  # the residual plot's width (the panel's layout follows it)
        self._panel_of: DescentResult | None = None  # the snapshot the panel shows (or will)
        self._panel_due: DescentResult | None = None  # to show when the dialog on top closes
        self._comparison_due = False  # a comparison arrived as a fit was due: drawn after it
        self.comparison: DayComparison | None = None  # the latest, rendered as comparison_text
        self.comparison_text = (
            "no comparison yet: it needs fitted descents with ski or wax entered (m)"
        )
        self.connection = "starting"
        self.connection_detail = ""
        self.problem = ""  # the latest failure the acquisition went on after (status line)
        self.sub_title = mode

    # ------------------------------------------------------------------ layout

    async def on_mount(self) -> None:
        self.main = MainScreen()
        await self.push_screen(self.main)
        self.columns = table_columns(self.size.width)
        self._build_table()
        # ↑ ↓, i and v work at once: the table has the focus from the start
        self.main.query_one("#table", DataTable).focus()
        self._update_status()
        self.on_resize()
        # what is here now (the libraries, the screen) lives as long as the app: out of the
        # garbage collector's way, or every full collection of the day walks it again (one
        # every two descents, ~150 ms of the UI's process each, whatever descent it fell in)
        runtime.freeze_long_lived()
        # and the full collections, which walk the day's objects (100–300 ms at descent 800),
        # run between descents, not whenever an allocation tips Python's count
        self.collector.start()
        self.set_interval(COLLECT_EVERY_S, self._collect_if_quiet)
        if self.mode == "replay" and self.recorded is not None:
            self.acq = self.recorded.start_replay(
                PostingListener(self), speed=self.speed, compare=True
            )
        else:  # the comparison: the acquisition's, in a process of its own, while shown
            self.acq = Acquisition.open(
                self.config,
                PostingListener(self),
                session_dir=self.session_dir,
                date=self.date,
                ski_rotation=self.demo_skis if self.mode == "demo" else (),
                compare=True,
            )
        self.photocell_ids = tuple(self.acq.track.photocell_ids)
        self.acq.show_comparison(True)  # the answer line shows it after every descent
        if self.session_dir is not None:
            self.sub_title = f"{self.mode} · {self.session_dir}"
        elif self.source is not None:  # a replay names what it replays: the session's name
            self.sub_title = f"{self.mode} · {os.path.basename(os.path.normpath(self.source))}"
        if self.mode == "replay":
            assert self.source is not None
            if self.recorded is None:  # a plain capture
                self.acq.start_replay(self.source, self.speed)
        elif self.mode == "demo":
            self.run_worker(self._start_demo, thread=True, group="demo", exit_on_error=False)
        else:
            self.acq.start_serial()

    def _start_demo(self) -> None:
        """In a worker thread: start the simulated timer, then read it."""
        assert self.sim is not None and self.acq is not None
        try:
            port = self.sim.start()
        except SimulatorError as exc:
            self.post_message(ConnectionChanged("error", str(exc)))
            return
        serial = self.acq.config.serial
        self.acq.start_serial(replace(serial, port=port))

    def on_resize(self, _event: object = None) -> None:
        """Called by the main screen when the terminal changes size."""
        if not self.columns:  # before the main screen is mounted
            return
        self.set_class(self.size.width < NARROW, "narrow")
        if table_columns(self.size.width) != self.columns:
            self._build_table()
        # the plots grow with the terminal's height; the table keeps at least 6 rows at 24
        self.plot_rows = max(6, min(16, 6 + (self.size.height - 30) // 2))
        self.main.query_one("#plots").styles.height = self.plot_rows
        self.main.query_one("#top").styles.height = 2 + 6 + self.plot_rows
        self.call_after_refresh(self._draw_plots)

    # ------------------------------------------------------------------ the table

    def _build_table(self) -> None:
        """The columns for the terminal's width, and every row again; the selection is kept."""
        table = self.main.query_one("#table", DataTable)
        selected = self._cursor_number()
        self.columns = table_columns(self.size.width)
        table.clear(columns=True)
        for col in self.columns:
            label = " " + (col.label.rjust(col.width) if col.number else col.label)
            table.add_column(label, key=col.key, width=col.width + 1)
        for n in sorted(self.results):
            table.add_row(*self._cells(self.results[n]), key=str(n))
        if selected is not None and str(selected) in table.rows:
            table.move_cursor(row=table.get_row_index(str(selected)))

    def _cells(self, res: DescentResult) -> list[str]:
        return [justify(cell(res, col), col) for col in self.columns]

    def _cursor_number(self) -> int | None:
        """The descent of the selected row (None: no rows yet)."""
        table = self.main.query_one("#table", DataTable)
        if table.row_count == 0:
            return None
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key
        return int(key.value) if key.value is not None else None

    # ------------------------------------------------------------------ messages

    def on_connection_changed(self, msg: ConnectionChanged) -> None:
        # the state first, the port (or why) last: at 80 columns the counts stay in sight
        states = {
            "connected": "timer connected",
            "disconnected": "TIMER DISCONNECTED · reconnecting",
            "open-failed": "cannot open the timer port · retrying",
            "replay": "replaying",
            "error": "ERROR",
        }
        self.connection = states.get(msg.state, msg.state)
        self.connection_detail = msg.detail
        self.set_class(msg.state in ("disconnected", "open-failed", "error"), "offline")
        self._update_status()

    def _update_status(self) -> None:
        c = self.counts
        counts = f"{c.impulses} impulses · {c.edits} edits · {c.unparsed} unparsed"
        problem = f"  │  ! {self.problem}" if self.problem else ""
        detail = f"  │  {self.connection_detail}" if self.connection_detail else ""
        # one line of a fixed height and the screen's width: no layout needed
        self.main.query_one("#status", Static).update(
            f" {self.connection}  │  {counts}{problem}{detail}", layout=False
        )

    def on_impulses_arrived(self, msg: ImpulsesArrived) -> None:
        self.counts = msg.counts
        lines = []
        for e in msg.events:
            where = f"{e.channel}→{e.photocell}" if e.photocell else e.channel
            fate = f"#{e.descent}" if e.kept else f"✗ {e.reason}"
            lines.append(f"{format_tod(e.tod_us, 4)} {where:<8} {fate}")
        if self._holding or self._fit_imminent():
            self._hold(lines)
            return
        self._update_status()
        if lines:  # one write: the log (500 lines at most) is drawn once for the chunk
            self.main.query_one("#log", RichLog).write("\n".join(lines))

    @property
    def _holding(self) -> bool:
        """Whether lines are held for a fit: exactly while the timer that releases them runs."""
        return self._hold_timer is not None

    def _hold(self, lines: list[str]) -> None:
        """The last impulse of a descent, and what comes with it, drawn with its fit: a frame
        of their own (the whole screen behind a dialog, ~6 ms at 120×40) took the UI's
        thread while the fit was being computed, and the fit's frame came after it."""
        if self._hold_timer is None:
            self._hold_timer = self.set_timer(HOLD_S, self._release)
        self._held_log += lines

    def _release(self) -> None:
        """What was held for the fit, drawn (with it, or HOLD_S later if none came)."""
        timer, self._hold_timer = self._hold_timer, None
        if timer is None:
            return
        timer.stop()
        lines, self._held_log = self._held_log, []
        text, self._held_progress = self._held_progress, None
        self._update_status()
        if lines:
            self.main.query_one("#log", RichLog).write("\n".join(lines))
        if text is not None:
            self.main.query_one("#progress", Static).update(text, layout=False)

    def on_descent_progress(self, msg: DescentProgress) -> None:
        p = self.progress = msg.progress
        ids = self.photocell_ids
        if p.number is None:
            text = "no descent running · waiting for the start photocell " + ids[0]
        else:
            t0 = p.times_us[0]
            passed = dict(zip(p.passed, p.times_us, strict=True))
            marks = " ".join(f"{'●' if pc in passed else '○'}{pc}" for pc in ids)
            last = p.passed[-1]
            text = (
                f"descent {p.number} running: {len(p.passed)}/{len(ids)} · "
                f"{last} +{(passed[last] - t0) / 1e6:.2f} s\n{marks}"
            )
        if self._holding:  # the descent's end: shown with its fit
            self._held_progress = text
        else:
            self.main.query_one("#progress", Static).update(text, layout=False)  # 2 lines, fixed
        if isinstance(self.screen, MetadataScreen):  # a descent started while it is open
            self.screen.set_next(p.next_number)
        if self._comparison_due and not self._fit_imminent():  # no fit came (aborted)
            self._show_comparison()

    def on_descent_fitted(self, msg: DescentFitted) -> None:
        res = msg.result
        n = res.number
        # its speed curve (12 kB) only while it is shown, its fit (4 kB) in the session's
        # fit store where it has one: read back, drawn again when selected (DescentResult.lean)
        self.results[n] = res.lean()
        table = self.main.query_one("#table", DataTable)
        key = str(n)
        values = self._cells(res)
        if key in table.rows:
            for col, value in zip(self.columns, values, strict=True):
                table.update_cell(key, col.key, value)
        else:
            # follow new descents only when the cursor is on the last row: a selection the
            # engineer made (to mark or refit a descent) is never taken away
            following = table.row_count == 0 or table.cursor_row >= table.row_count - 1
            table.add_row(*values, key=key)
            if following:
                table.move_cursor(row=table.row_count - 1, scroll=True)
        self.latest = n
        self._fitted_at = time.monotonic()
        self.set_timer(COLLECT_AFTER_S, self._collect_after_fit)
        if self._comparison_due:  # the comparison that waited for this fit, after its frame
            self.call_after_refresh(self._show_comparison)
        # the panel shows the selected row, and only it: "the descent" is one descent
        if self._cursor_number() == n:
            self._show(res)
        self._release()  # the last impulse, the counts and the progress, in the fit's frame

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is None or event.row_key.value is None:
            return
        if event.cursor_row != event.data_table.cursor_row:
            return  # the cursor moved on meanwhile (descents arriving in bulk): no panel for it
        n = int(event.row_key.value)
        res = self.results.get(n)
        if res is None:
            return
        if self.shown == n and self._panel_of is res:
            return  # the new descent the table moved to: its fit is shown (or due) already
        self._show(res)

    def _main_covered(self) -> bool:
        """A dialog (the comparison, the metadata form, the help) covers the main screen."""
        return self.screen is not self.main

    def on_main_uncovered(self) -> None:
        """The main screen is on top again: the panel drawn for the selected descent, if a
        fit arrived while a dialog covered it."""
        if self._panel_due is not None:
            self._show(self._panel_due)

    def on_comparison_updated(self, msg: ComparisonUpdated) -> None:
        self.comparison = msg.comparison
        self.comparison_text = comparison_view(msg.comparison)
        self.main.query_one("#answer", Static).update(headline(msg.comparison), layout=False)
        if self._fit_imminent():  # drawn after the fit: the long text's layout waits
            self._comparison_due = True
            return
        self._show_comparison()

    def _show_comparison(self) -> None:
        self._comparison_due = False
        if isinstance(self.screen, ComparisonScreen):
            self.screen.update(self.comparison_text)

    def _collect_after_fit(self) -> None:
        """A full garbage collection, if one is due and no other descent is about to end."""
        if not self._fit_imminent():
            self.collector.collect_if_due()

    def _collect_if_quiet(self) -> None:
        """A full garbage collection, if one is due and no descent has come for a while."""
        p = self.progress
        if (p is None or p.number is None) and time.monotonic() - self._fitted_at > QUIET_S:
            self.collector.collect_if_due()

    def _fit_imminent(self) -> bool:
        """The open descent has passed all but its last photocell: its fit is due any moment,
        and nothing else (the comparison's text) is drawn before it."""
        p = self.progress
        return (
            p is not None
            and p.number is not None
            and len(p.passed) >= max(1, len(self.photocell_ids) - 1)
        )

    def on_acquisition_warning(self, msg: AcquisitionWarning) -> None:
        # what came before it and waits for a fit, first: the log is read top to bottom
        self._release()
        self.problem = msg.text
        self._update_status()
        self.main.query_one("#log", RichLog).write(f"! {msg.text}")
        self.notify(msg.text, title="the recording goes on", severity="error", timeout=10)

    def action_compare(self) -> None:
        """The whole comparison, kept up to date while shown (it is computed after every
        descent, in a process of its own, for the answer line)."""
        self.push_screen(ComparisonScreen(self.comparison_text))

    def on_source_ended(self, msg: SourceEnded) -> None:
        self.connection = "replay finished"
        self._update_status()
        self.notify(msg.summary, title="replay finished", timeout=10)

    def _show(self, res: DescentResult) -> None:
        """Result panel and plots for one descent: drawn once per fit, and while a dialog
        covers the main screen not at all (the comparison, open all day, hides them): then
        when the dialog closes."""
        self.shown = res.number
        self._panel_of = self.results.get(res.number)  # the snapshot shown, or due
        if self._main_covered():
            self._panel_due = res
            return
        self._panel_due = None
        text = panel_text(res)
        if res.fit is None:
            self.main.query_one("#result", Static).update(text)
            self.main.query_one("#residuals", Static).update("")
            self._resid_width = 40  # its min-width
            self.main.query_one("#speed", Static).update("")
            self._plotted = None
            return
        self.main.query_one("#result", Static).update(text, layout=False)  # a fixed box
        self._plotted = res
        self._draw_plots()

    def _draw_plots(self) -> None:
        """Both plots fill their widgets: drawn again when the terminal is resized. Their
        widths come from the terminal's, not from the widgets' last layout (which lags one
        refresh behind the residual plot's new width)."""
        res = self._plotted
        if res is None:
            return
        rows = self.plot_rows
        # the left panel: the terminal less the log of impulses (hidden when narrow)
        left = self.size.width - (0 if self.size.width < NARROW else 46)
        resid_width = 40  # the residual plot's min-width (station.tcss)
        if res.fit is not None:
            text = residual_text(res.fit, left, rows)
            resid_width = max(resid_width, *(len(line) for line in text.splitlines()))
            # its width follows its text: laid out again only when that changes
            box = self.main.query_one("#residuals", Static)
            box.update(text, layout=resid_width != self._resid_width)
            self._resid_width = resid_width
        box = self.main.query_one("#speed", Static)
        width = max(10, left - resid_width - 1 - 7)  # its padding, the speed labels
        if res.speed_x is None and res.fit is not None and self.acq is not None:
            curve = self.acq.speed_curve(res)  # one model solve: kept while it is shown
            if curve is not None:
                res = self._plotted = replace(res, speed_x=curve[0], speed_v=curve[1])
        plot = speed_text(res, width, rows - 1)
        box.update(plot, layout=False)  # the rest of the row: a fixed box

    def on_unmount(self) -> None:
        """Quitting ends the day as Ctrl-C ends ``station record``: the open descent is ended
        and fitted, the results CSV written, the raw log closed.

        Python's garbage collector is given back first: a failure below (a port that raises
        as it closes) must not leave a process that goes on (a test, an embedding program)
        with no full collection ever, nor the app's objects frozen out of its reach."""
        self.collector.stop()
        runtime.thaw()
        try:
            if self.acq is not None:
                self.acq.stop()  # no more bytes: the simulator may go now
            if self.sim is not None:
                self.sim.terminate()  # it ends while the day is closed, not after
            if self.acq is not None:
                self.acq.close()
        finally:  # the simulator ends whatever happened above
            if self.sim is not None:
                self.sim.stop(timeout=0.05)
