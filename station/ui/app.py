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
from dataclasses import replace
from typing import Any

from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, RichLog, Static

from station.report.text import local_time
from station.session.acquisition import Acquisition
from station.session.analysis import DescentResult
from station.session.config import StationConfig
from station.session.records import (
    FitModel,
    InvalidMark,
    LineCounts,
    ModelChange,
    Progress,
    ValidMark,
)
from station.timing.impulses import format_tod
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
from station.ui.plots import residual_plot, speed_plot
from station.ui.screens import ComparisonScreen, HelpScreen, MetadataScreen, ReasonScreen
from station.ui.simulator import SimulatedTimer, SimulatorError

#: (label, key, width): fixed widths, so the table does not jump as rows arrive and the
#: columns that matter most fit in 80 columns
COLUMNS = [
    ("#", "n", 3), ("start", "start", 8), ("ski", "ski", 12), ("μ", "mu", 7),
    ("status", "status", 18), ("μ 90 %", "mu_ci", 15), ("CdA", "cda", 6), ("v0", "v0", 5),
    ("rms ms", "rms", 6), ("wax", "wax", 12), ("notes", "notes", 40),
]  # fmt: skip


def _f(v: Any, spec: str) -> str:
    return "—" if v is None or (isinstance(v, float) and v != v) else format(v, spec)


class MainScreen(Screen):
    """The one screen of the station; modal screens go on top of it."""

    def compose(self) -> ComposeResult:
        yield Header(show_clock=False)
        yield Static("", id="status")
        with Horizontal(id="top"):
            with Vertical(id="left"):
                yield Static("waiting for the first descent", id="progress")
                yield Static("no result yet", id="result")
                with Horizontal(id="plots"):
                    yield Static("", id="residuals")
                    yield Static("", id="speed")
            yield RichLog(id="log", max_lines=500, markup=False, wrap=False)
        yield DataTable(id="table", cursor_type="row", zebra_stripes=True)
        yield Footer()

    def on_resize(self, _event: object) -> None:
        self.app.on_resize()  # type: ignore[attr-defined]


class StationApp(App):
    """One session at the trackside."""

    CSS_PATH = "station.tcss"
    TITLE = "station"
    BINDINGS = [
        Binding("m", "metadata", "Metadata"),
        Binding("i", "invalid", "Invalid"),
        Binding("v", "refit", "Velocity fit"),
        Binding("e", "export", "Export CSV"),
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
    ) -> None:
        super().__init__()
        self.mode = mode
        self.source = source
        self.session_dir = session_dir
        self.speed = speed
        self.date = date
        self.sim = SimulatedTimer(sim_command) if sim_command else None
        self.demo_skis = demo_skis or []
        self.config = config
        self.acq: Acquisition | None = None
        self.photocell_ids: tuple[str, ...] = ()
        # what the messages brought: the UI's own snapshots of the day
        self.results: dict[int, DescentResult] = {}
        self.progress: Progress | None = None
        self.counts = LineCounts()
        self.metadata_from: int | None = None  # where the latest metadata entered applies from
        self.latest: int | None = None
        self.comparison_text = (
            "no comparison yet: it needs fitted descents with ski or wax entered (m)"
        )
        self.connection = "starting"
        self.problem = ""  # the latest failure the acquisition went on after (status line)
        self.sub_title = mode

    # ------------------------------------------------------------------ layout

    async def on_mount(self) -> None:
        self.main = MainScreen()
        await self.push_screen(self.main)
        table = self.main.query_one("#table", DataTable)
        for label, key, width in COLUMNS:
            table.add_column(label, key=key, width=width)
        self._update_status()
        self.on_resize()
        self.acq = Acquisition.open(
            self.config,
            PostingListener(self),
            session_dir=self.session_dir,
            date=self.date,
            compare=True,
            ski_rotation=self.demo_skis if self.mode == "demo" else (),
        )
        self.photocell_ids = tuple(self.acq.track.photocell_ids)
        if self.session_dir is not None:
            self.sub_title = f"{self.mode} · {self.session_dir}"
        if self.mode == "replay":
            assert self.source is not None
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
        self.set_class(self.size.width < 110, "narrow")
        self.call_after_refresh(self._draw_speed)

    # ------------------------------------------------------------------ messages

    def on_connection_changed(self, msg: ConnectionChanged) -> None:
        states = {
            "connected": f"timer connected: {msg.detail}",
            "disconnected": f"TIMER DISCONNECTED ({msg.detail}) · reconnecting",
            "open-failed": f"cannot open the timer port ({msg.detail}) · retrying",
            "replay": f"replaying {msg.detail}",
            "error": f"ERROR: {msg.detail}",
        }
        self.connection = states.get(msg.state, msg.state)
        self.set_class(msg.state in ("disconnected", "open-failed", "error"), "offline")
        self._update_status()

    def _update_status(self) -> None:
        c = self.counts
        counts = f"{c.impulses} impulses · {c.edits} edits · {c.unparsed} unparsed"
        problem = f"  │  ! {self.problem}" if self.problem else ""
        self.main.query_one("#status", Static).update(f" {self.connection}  │  {counts}{problem}")

    def on_impulses_arrived(self, msg: ImpulsesArrived) -> None:
        self.counts = msg.counts
        self._update_status()
        log = self.main.query_one("#log", RichLog)
        for e in msg.events:
            where = f"{e.channel}→{e.photocell}" if e.photocell else e.channel
            fate = f"#{e.descent}" if e.kept else f"✗ {e.reason}"
            log.write(f"{format_tod(e.tod_us, 4)} {where:<8} {fate}")

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
        self.main.query_one("#progress", Static).update(text)

    def on_descent_fitted(self, msg: DescentFitted) -> None:
        res = msg.result
        n = res.number
        self.results[n] = res
        row = res.row
        ci = f"{_f(row.mu_lo, '.5f')}–{_f(row.mu_hi, '.5f')}" if row.mu_lo is not None else "—"
        status = row.status.value if not row.invalid else "INVALID"
        values = [
            str(n),
            res.start_time[11:19] if "T" in res.start_time else res.start_time[:8],
            row.ski,
            _f(row.mu, ".5f"),
            status + (" (v)" if row.model == FitModel.VELOCITY else ""),
            ci,
            _f(row.cda, ".4f"),
            _f(row.v0, ".2f"),
            _f(row.rms_residual_ms, ".2f"),
            row.wax,
            row.invalid_reason or "; ".join(row.flags),
        ]
        table = self.main.query_one("#table", DataTable)
        key = str(n)
        if key in table.rows:
            for (_label, col, _width), value in zip(COLUMNS, values, strict=True):
                table.update_cell(key, col, value)
        else:
            # follow new descents only when the cursor is on the last row: a selection the
            # engineer made (to mark or refit a descent) is never taken away
            following = table.row_count == 0 or table.cursor_row >= table.row_count - 1
            table.add_row(*values, key=key)
            if following:
                table.move_cursor(row=table.row_count - 1)
        self.latest = n
        self._show(res)

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if event.row_key is None or event.row_key.value is None:
            return
        res = self.results.get(int(event.row_key.value))
        if res is not None:
            self._show(res)

    def on_comparison_updated(self, msg: ComparisonUpdated) -> None:
        self.comparison_text = msg.text
        if isinstance(self.screen, ComparisonScreen):
            self.screen.update(msg.text)

    def on_acquisition_warning(self, msg: AcquisitionWarning) -> None:
        self.problem = msg.text
        self._update_status()
        self.main.query_one("#log", RichLog).write(f"! {msg.text}")
        self.notify(msg.text, title="the recording goes on", severity="error", timeout=10)

    def action_compare(self) -> None:
        self.push_screen(ComparisonScreen(self.comparison_text))

    def on_source_ended(self, msg: SourceEnded) -> None:
        self.connection = "replay finished"
        self._update_status()
        self.notify(msg.summary, title="replay finished", timeout=10)

    def _show(self, res: DescentResult) -> None:
        """Result panel and plots for one descent."""
        f, row, d = res.fit, res.row, res.descent
        head = f"descent {d.number} · {local_time(res.start_time)} · "
        if f is None:
            self.main.query_one("#result", Static).update(
                head + f"{row.status}: {'; '.join(row.flags)}"
            )
            self.main.query_one("#residuals", Static).update("")
            self.main.query_one("#speed", Static).update("")
            return
        e, ci = f.estimates, f.ci90

        def line(label: str, key: str, spec: str, unit: str) -> str:
            c = ci.get(key)
            if c:
                rng = f"[{format(c[0], spec)}, {format(c[1], spec)}]"
            elif key in f.not_identifiable:
                rng = "not identifiable"
            else:
                rng = "no interval"
            return f"{label:<4}{_f(e.get(key), spec):>9} {unit:<4} {rng}"

        status = row.status.value
        if row.invalid:
            status = f"INVALID: {row.invalid_reason} (fit {status})"
        text = (
            head
            + f"{len(d.photocells)} photocells · {status}\n"
            + line("μ", "mu", ".5f", "")
            + "   "
            + line("CdA", "cda", ".4f", "m²")
            + "\n"
            + line("v0", "v0", ".3f", "m/s")
            + f"   rms {_f(row.rms_residual_ms, '.2f')} ms · {row.model} model"
            + (  # the velocity model's μ1: always with its interval, flagged when ∋ 0
                "\n"
                + line("μ1", "mu1", ".2e", "s/m")
                + ("  (not distinguishable from 0)" if "mu1" in f.consistent_with_zero else "")
                if "mu1" in e
                else ""
            )
            + (f"\n{f.message}" if f.message else "")
        )
        self.main.query_one("#result", Static).update(text)
        ids = list(f.residuals_s)
        plot = residual_plot(ids, [r * 1000 for r in f.residuals_s.values()], height=6)
        self.main.query_one("#residuals", Static).update(
            "\n".join(plot) if ids else "no residuals: " + f.status
        )
        self._speed_of = res
        self._draw_speed()

    def _draw_speed(self) -> None:
        """The speed plot fills its widget: drawn again when the terminal is resized."""
        res = getattr(self, "_speed_of", None)
        if res is None:
            return
        box = self.main.query_one("#speed", Static)
        width = max(10, box.content_region.width - 7)
        if res.speed_x is not None and res.speed_v is not None:
            plot = speed_plot(res.speed_x, res.speed_v, width=width, height=5)
        else:
            plot = ["(no speed profile)"]
        self.main.query_one("#speed", Static).update("\n".join(plot))

    # ------------------------------------------------------------------ actions

    def _selected(self) -> int | None:
        table = self.main.query_one("#table", DataTable)
        if table.row_count == 0:
            self.notify("no descent yet", severity="warning")
            return None
        key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key
        return int(key.value) if key.value is not None else None

    def action_help(self) -> None:
        self.push_screen(HelpScreen())

    def action_metadata(self) -> None:
        p = self.progress
        nxt = p.next_number if p is not None else 1
        current = p.next_metadata.values() if p is not None else {}

        def done(values: dict[str, Any] | None) -> None:
            if values is None or self.acq is None:
                return
            start = self.metadata_from = self.acq.add_metadata(values)
            self.notify(f"metadata applies from descent {start} on")

        self.push_screen(MetadataScreen(current, nxt), done)

    def action_invalid(self) -> None:
        n = self._selected()
        if n is None or self.acq is None:
            return
        res = self.results.get(n)
        if res is not None and res.row.invalid:
            self.acq.annotate(ValidMark(n))
            self.notify(f"descent {n} valid again")
            return

        def done(reason: str | None) -> None:
            if reason is not None and self.acq is not None:
                self.acq.annotate(InvalidMark(n, reason))
                self.notify(f"descent {n} marked invalid: {reason}")

        self.push_screen(ReasonScreen(n), done)

    def action_refit(self) -> None:
        n = self._selected()
        if n is None or self.acq is None:
            return
        res = self.results.get(n)
        current = res.row.model if res is not None else FitModel(self.config.model)
        model = FitModel.CONSTANT if current == FitModel.VELOCITY else FitModel.VELOCITY
        self.acq.annotate(ModelChange(n, model))
        self.notify(f"refitting descent {n} with the {model} model")

    def action_export(self) -> None:
        if self.acq is None:
            return
        if self.session_dir is not None:
            from station.session.store import RESULTS

            path = os.path.join(self.session_dir, RESULTS)
        else:
            base = os.path.splitext(os.path.basename(os.path.normpath(self.source or "replay")))[0]
            path = os.path.abspath(f"{base}-results.csv")
        try:
            self.acq.write_csv(path)
        except OSError as exc:
            self.notify(f"{path} not written: {exc}", severity="error")
            return
        self.notify(f"{len(self.results)} descents exported to {path}")

    def on_unmount(self) -> None:
        """Quitting ends the day as Ctrl-C ends ``station record``: the open descent is ended
        and fitted, the results CSV written, the raw log closed."""
        if self.acq is not None:
            self.acq.close()
        if self.sim is not None:
            self.sim.stop()
