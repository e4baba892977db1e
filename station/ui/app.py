"""The trackside UI: live from a timer, a demo with the simulated timer, or a replay.

Threads: the *acquisition* worker reads the serial port (or a replay), writes every chunk to
the raw log first, then parses and assembles under the day's lock; the *fit* worker fits
finished descents and applies annotations. Both talk to the UI only through messages
(:mod:`station.ui.messages`); the UI thread never parses, fits or reads the port.
"""

from __future__ import annotations

import datetime as dt
import os
import queue
import subprocess
import threading
import time
from dataclasses import replace
from typing import Any

from textual.app import App, ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.screen import Screen
from textual.widgets import DataTable, Footer, Header, RichLog, Static

from station.session import store as sessions
from station.session.analysis import DescentResult
from station.session.config import StationConfig
from station.session.day import Day
from station.session.rawlog import Chunk, RawLogWriter
from station.session.recorder import replay_chunks
from station.session.results import write_results
from station.survey.load import load_survey
from station.survey.track import build_track
from station.timing.impulses import format_tod
from station.ui.messages import (
    ComparisonUpdated,
    ConnectionChanged,
    DescentFitted,
    DescentProgress,
    ImpulsesArrived,
    SourceEnded,
)
from station.ui.plots import residual_plot, speed_plot
from station.ui.screens import ComparisonScreen, HelpScreen, MetadataScreen, ReasonScreen

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
        self.sim_command = sim_command
        self.demo_skis = demo_skis or []
        self.sim: subprocess.Popen | None = None
        self.config = config
        self.track = build_track(load_survey(config.survey_path))
        self.day = Day.start(config, self.track, date)
        self.lock = threading.Lock()
        self.jobs: queue.Queue = queue.Queue()
        self.rawlog: RawLogWriter | None = None
        self.reader: Any = None  # a SerialReader while live; serial is imported lazily
        self.stop_event = threading.Event()
        self.latest: int | None = None
        self._announced: int | None = None
        self.comparison_text = (
            "no comparison yet: it needs fitted descents with ski or wax entered (m)"
        )
        self.counts: dict[str, int] = {}
        self.connection = "starting"
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
        if self.session_dir is not None:
            sessions.create(self.config, self.session_dir)
            self.config = sessions.load_session_config(self.session_dir)
            self.day = Day.start(self.config, self.track, self.day.date)
            self.rawlog = RawLogWriter(
                os.path.join(self.session_dir, sessions.RAW),
                header={"port": self.config.serial.port, "protocol": self.config.serial.protocol},
            )
            self.sub_title = f"{self.mode} · {self.session_dir}"
        if self.mode == "demo" and self.demo_skis:
            self._annotate({"type": "metadata", "from": 1, "values": {"ski": self.demo_skis[0]}})
        self.run_worker(self._fit_loop, thread=True, group="fit", exit_on_error=False)
        if self.mode == "replay":
            self.run_worker(
                self._replay_loop, thread=True, group="acquisition", exit_on_error=False
            )
        else:
            self.run_worker(self._live_loop, thread=True, group="acquisition", exit_on_error=False)

    def on_resize(self, _event: object = None) -> None:
        """Called by the main screen when the terminal changes size."""
        self.set_class(self.size.width < 110, "narrow")
        self.call_after_refresh(self._draw_speed)

    # ------------------------------------------------------------------ workers (threads)

    def _after_feed(self, first_event: int, done: list) -> None:
        """Called with the lock held: tell the UI what the chunk did, queue finished descents."""
        proc = self.day.processor
        new = proc.events[first_event:]
        if new:
            self.post_message(ImpulsesArrived(list(new), dict(proc.counts)))
        if new or done:
            cur = proc.assembler.current
            if cur is not None and cur.number != self._announced:
                self._announced = cur.number
                self._new_descent(cur.number)
            self.post_message(
                DescentProgress(
                    cur.number if cur else None,
                    list(cur.photocells) if cur else [],
                    list(cur.times_us) if cur else [],
                )
            )
        for d in done:
            self.jobs.put(("descent", d))

    def _new_descent(self, number: int) -> None:
        """A descent started: in the demo, the next pair of skis is already waiting."""
        if self.mode == "demo" and self.demo_skis:
            ski = self.demo_skis[number % len(self.demo_skis)]
            self._annotate_locked({"type": "metadata", "from": number + 1, "values": {"ski": ski}})

    def _feed(self, chunk: Chunk) -> None:
        with self.lock:
            n = len(self.day.processor.events)
            done = self.day.processor.feed(chunk)
            self._after_feed(n, done)

    def _live_loop(self) -> None:
        from station.session.serialport import SerialReader

        cfg = self.config
        if self.mode == "demo":
            port = self._start_simulator()
            if port is None:
                return
            cfg = replace(cfg, serial=replace(cfg.serial, port=port))

        def on_chunk(t: float, data: bytes) -> None:
            if self.rawlog is not None:
                self.rawlog.write(t, data)  # first: on disk before it is parsed
            self._feed(Chunk(t, data))

        def on_event(t: float, event: str, detail: str) -> None:
            if self.rawlog is not None:
                self.rawlog.event(t, event, detail)
            self._feed(Chunk(t, b"", event, detail))
            self.post_message(ConnectionChanged(event, detail))

        def on_idle(t: float) -> None:
            with self.lock:
                done = self.day.processor.tick(t)
                if done:
                    if self.rawlog is not None:
                        self.rawlog.event(t, "timeout")
                    self._after_feed(len(self.day.processor.events), done)
            if self.stop_event.is_set():
                reader.stop()

        reader = SerialReader(cfg.serial, on_chunk, on_event, on_idle)
        self.reader = reader
        reader.run()
        if reader.error is not None:
            self.post_message(ConnectionChanged("error", str(reader.error)))

    def _start_simulator(self) -> str | None:
        assert self.sim_command is not None
        try:
            self.sim = subprocess.Popen(
                self.sim_command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
            )
        except OSError as exc:
            self.post_message(
                ConnectionChanged("error", f"cannot start the simulated timer: {exc}")
            )
            return None
        first = self.sim.stdout.readline() if self.sim.stdout else ""
        if not first.startswith("PORT "):
            self.post_message(ConnectionChanged("error", "the simulated timer did not start"))
            return None
        return first.split(" ", 1)[1].strip()

    def _replay_loop(self) -> None:
        assert self.source is not None
        if sessions.is_session(self.source):
            for record in sessions.read_annotations(self.source):
                with self.lock:
                    self.day.annotate(record)
        self.post_message(
            ConnectionChanged("replay", os.path.basename(os.path.normpath(self.source)))
        )
        for chunk in replay_chunks(self.source, self.speed, self.stop_event):
            self._feed(chunk)
        if self.stop_event.is_set():
            return
        with self.lock:
            self._after_feed(len(self.day.processor.events), self.day.processor.finish())
        self.jobs.put(("ended", None))

    def _fit_loop(self) -> None:
        while True:
            kind, payload = self.jobs.get()
            if kind == "stop":
                return
            if kind == "ended":
                with self.lock:
                    from station.session.recorder import Run

                    summary = Run(self.day).summary()
                self.post_message(SourceEnded(summary))
                continue
            from station.model.compare import collect

            with self.lock:
                res = self.day.analyse(payload) if kind == "descent" else self.day.annotate(payload)
                self._write_results()
                snapshot = collect(self.day)
            if res is not None:
                self.post_message(DescentFitted(res))
            # the joint fit of the whole day runs outside the lock: the reader goes on meanwhile
            self.post_message(ComparisonUpdated(self._comparison(*snapshot)))

    def _comparison(self, data: list, excluded: list, windy: list) -> str:
        """The joint fit of the session's valid descents, as text."""
        from station.model.compare import CompareError, format_comparison, joint_fit

        if len(data) < 2:
            return "no comparison yet: it needs at least two fitted descents"
        try:
            res = joint_fit(self.track, data)
        except CompareError as exc:
            return f"no comparison yet: {exc}"
        res.excluded, res.wind_flagged = excluded, windy
        return format_comparison(res, len(data)) + "".join(f"\n! {w}" for w in res.warnings)

    def _write_results(self) -> None:
        """With the lock held: the session's results CSV, rewritten after every change."""
        if self.session_dir is None:
            return
        header = sessions.results_header(self.config, self.track.name)
        write_results(self.day.rows(), os.path.join(self.session_dir, sessions.RESULTS), header)

    # ------------------------------------------------------------------ annotations

    def _annotate_locked(self, record: dict[str, Any]) -> None:
        """With the lock held (or from the acquisition thread): store and apply a metadata
        annotation at once, so the descent it is for sees it."""
        record = {"t": time.time(), **record}
        if self.session_dir is not None:
            sessions.append_annotation(self.session_dir, record)
        self.day.annotate(record)

    def _annotate(self, record: dict[str, Any]) -> None:
        with self.lock:
            self._annotate_locked(record)

    def _queue_annotation(self, record: dict[str, Any]) -> None:
        """Invalid marks and refits: stored now, applied (and refitted) by the fit worker."""
        record = {"t": time.time(), **record}
        if self.session_dir is not None:
            sessions.append_annotation(self.session_dir, record)
        self.jobs.put(("annotate", record))

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
        counts = (
            f"{c.get('impulse', 0)} impulses · {c.get('edit', 0)} edits · "
            f"{c.get('unparsed', 0)} unparsed"
        )
        self.main.query_one("#status", Static).update(f" {self.connection}  │  {counts}")

    def on_impulses_arrived(self, msg: ImpulsesArrived) -> None:
        self.counts = msg.counts
        self._update_status()
        log = self.main.query_one("#log", RichLog)
        for e in msg.events:
            where = f"{e.channel}→{e.photocell}" if e.photocell else e.channel
            fate = f"#{e.descent}" if e.kept else f"✗ {e.reason}"
            log.write(f"{format_tod(e.tod_us, 4)} {where:<8} {fate}")

    def on_descent_progress(self, msg: DescentProgress) -> None:
        ids = self.track.photocell_ids
        if msg.number is None:
            text = "no descent running · waiting for the start photocell " + ids[0]
        else:
            t0 = msg.times_us[0]
            passed = dict(zip(msg.passed, msg.times_us, strict=True))
            marks = " ".join(f"{'●' if p in passed else '○'}{p}" for p in ids)
            last = msg.passed[-1]
            text = (
                f"descent {msg.number} running: {len(msg.passed)}/{len(ids)} · "
                f"{last} +{(passed[last] - t0) / 1e6:.2f} s\n{marks}"
            )
        self.main.query_one("#progress", Static).update(text)

    def on_descent_fitted(self, msg: DescentFitted) -> None:
        res = msg.result
        n = res.descent.number
        row = res.row
        ci = (
            f"{_f(row['mu_lo'], '.5f')}–{_f(row['mu_hi'], '.5f')}"
            if row.get("mu_lo") is not None
            else "—"
        )
        status = row["status"] if not row.get("invalid_reason") else "INVALID"
        values = [
            str(n),
            res.start_time[11:19] if "T" in res.start_time else res.start_time[:8],
            row.get("ski") or "",
            _f(row.get("mu"), ".5f"),
            status + (" (v)" if row.get("model") == "velocity" else ""),
            ci,
            _f(row.get("cda"), ".4f"),
            _f(row.get("v0"), ".2f"),
            _f(row.get("rms_residual_ms"), ".2f"),
            row.get("wax") or "",
            row.get("invalid_reason") or row.get("flags") or "",
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
        res = self.day.results.get(int(event.row_key.value))
        if res is not None:
            self._show(res)

    def on_comparison_updated(self, msg: ComparisonUpdated) -> None:
        self.comparison_text = msg.text
        if isinstance(self.screen, ComparisonScreen):
            self.screen.update(msg.text)

    def action_compare(self) -> None:
        self.push_screen(ComparisonScreen(self.comparison_text))

    def on_source_ended(self, msg: SourceEnded) -> None:
        self.connection = "replay finished"
        self._update_status()
        self.notify(msg.summary, title="replay finished", timeout=10)

    def _show(self, res: DescentResult) -> None:
        """Result panel and plots for one descent."""
        f, row, d = res.fit, res.row, res.descent
        head = f"descent {d.number} · {res.start_time.replace('T', ' ')[:22]} · "
        if f is None:
            self.main.query_one("#result", Static).update(
                head + f"{d.status}: {'; '.join(d.flags)}"
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

        status = row["status"]
        if row.get("invalid_reason"):
            status = f"INVALID: {row['invalid_reason']} (fit {status})"
        text = (
            head
            + f"{len(d.photocells)} photocells · {status}\n"
            + line("μ", "mu", ".5f", "")
            + "   "
            + line("CdA", "cda", ".4f", "m²")
            + "\n"
            + line("v0", "v0", ".3f", "m/s")
            + f"   rms {_f(row.get('rms_residual_ms'), '.2f')} ms · {row.get('model')} model"
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
        with self.lock:
            nxt = self.day.next_number()
            current = self.day.metadata_for(nxt)

        def done(values: dict[str, Any] | None) -> None:
            if values is None:
                return
            with self.lock:
                start = self.day.next_number()
                self._annotate_locked({"type": "metadata", "from": start, "values": values})
            self.notify(f"metadata applies from descent {start} on")

        self.push_screen(MetadataScreen(current, nxt), done)

    def action_invalid(self) -> None:
        n = self._selected()
        if n is None:
            return
        if n in self.day.invalid:
            self._queue_annotation({"type": "valid", "descent": n})
            self.notify(f"descent {n} valid again")
            return

        def done(reason: str | None) -> None:
            if reason is not None:
                self._queue_annotation({"type": "invalid", "descent": n, "reason": reason})
                self.notify(f"descent {n} marked invalid: {reason}")

        self.push_screen(ReasonScreen(n), done)

    def action_refit(self) -> None:
        n = self._selected()
        if n is None:
            return
        current = self.day.models.get(n, self.config.model)
        model = "constant" if current == "velocity" else "velocity"
        self._queue_annotation({"type": "model", "descent": n, "model": model})
        self.notify(f"refitting descent {n} with the {model} model")

    def action_export(self) -> None:
        if self.session_dir is not None:
            path = os.path.join(self.session_dir, sessions.RESULTS)
        else:
            base = os.path.splitext(os.path.basename(os.path.normpath(self.source or "replay")))[0]
            path = os.path.abspath(f"{base}-results.csv")
        with self.lock:
            header = sessions.results_header(self.config, self.track.name)
            write_results(self.day.rows(), path, header)
            n = len(self.day.results)
        self.notify(f"{n} descents exported to {path}")

    def on_unmount(self) -> None:
        self.stop_event.set()
        if self.reader is not None:
            self.reader.stop()
        self.jobs.put(("stop", None))
        if self.sim is not None:
            self.sim.terminate()
            try:
                self.sim.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.sim.kill()
        if self.rawlog is not None:
            with self.lock:
                self._write_results()
            self.rawlog.close()
