"""What keeps the UI's work off a fit's way to the screen: full garbage collections only
between descents (IdleCollector, station/runtime.py), and a table that keeps nothing per row
it does not draw (station/ui/table.py). The latency itself is measured by
benchmarks/ui_fit_latency.py, not here."""

from __future__ import annotations

import asyncio
import gc
import os

import pytest
from textual.app import App, ComposeResult

from station import runtime
from station.runtime import NEVER, IdleCollector
from station.ui.table import ResultsTable
from tests.test_ui import replay_app, wait_for, wait_for_replay


@pytest.fixture
def full_collections():
    """The full collections that ran, whoever started them."""
    seen: list[int] = []

    def note(phase: str, info: dict) -> None:
        if phase == "stop" and info["generation"] == 2:
            seen.append(1)

    gc.callbacks.append(note)
    yield seen
    gc.callbacks.remove(note)


def grow(n: int) -> list[list[int]]:
    """Objects that live on (as a day's do): they pass through the young generations."""
    return [[i] for i in range(n)]


def test_python_starts_no_full_collection_while_the_ui_decides(full_collections):
    saved = gc.get_threshold()
    col = IdleCollector()
    col.start()
    try:
        assert gc.get_threshold() == (saved[0], saved[1], NEVER)
        kept = grow(400_000)  # ~57 middle collections: Python would start full ones
        assert gc.get_count()[2] > saved[2]
        assert full_collections == []
        assert col.collect_if_due() and len(full_collections) == 1  # when the UI asks
        assert gc.get_count()[2] == 0
        assert not col.collect_if_due()  # none due right after one
        del kept
    finally:
        col.stop()
    assert gc.get_threshold() == saved
    kept = grow(400_000)
    assert full_collections != [1]  # Python's own again (the check above means something)
    del kept


def test_a_full_collection_waits_ten_times_its_length(monkeypatch, full_collections):
    col = IdleCollector()
    col.start()
    clock = [100.0]
    monkeypatch.setattr(runtime.time, "monotonic", lambda: clock[0])
    real_collect = gc.collect

    def collect(generation: int = 2) -> int:
        clock[0] += 0.2  # a full collection of 0.2 s
        return real_collect(generation)

    monkeypatch.setattr(runtime.gc, "collect", collect)
    try:
        kept = grow(200_000)
        assert col.collect_if_due()
        kept += grow(200_000)
        assert gc.get_count()[2] > col.saved[2]  # due by Python's count, not yet by time
        clock[0] += 1.9
        assert not col.collect_if_due()
        clock[0] += 0.2  # past 2 s after the end of the last one: 10 × 0.2 s
        assert col.collect_if_due() and col.collections == 2
        assert col.seconds == pytest.approx(0.4)
        del kept
    finally:
        col.stop()


def test_the_app_decides_while_it_runs_and_gives_python_its_thresholds_back(tmp_path, demo_track):
    saved = gc.get_threshold()
    app = replay_app(tmp_path, demo_track)

    async def run() -> None:
        async with app.run_test(size=(100, 30)) as pilot:
            await wait_for_replay(pilot, app)
            assert gc.get_threshold()[2] == NEVER
            grow(400_000)  # a long day's worth of middle collections, then a fit
            await pilot.press("v")  # a refit of the selected descent: a fit after the count
            await wait_for(pilot, lambda: app.collector.collections >= 1, timeout=20)

    asyncio.run(run())
    assert gc.get_threshold() == saved


class OneTable(App):
    def compose(self) -> ComposeResult:
        yield ResultsTable(cursor_type="row", cell_padding=0)


def test_the_table_measures_and_keeps_nothing_for_fixed_width_columns():
    """DataTable measured every new row's cells and kept their Rich Texts (the last 1000 rows,
    11 Texts each: objects every full collection walked); the size is the same without."""

    async def run() -> tuple:
        app = OneTable()
        async with app.run_test(size=(80, 24)) as pilot:
            table = app.query_one(ResultsTable)
            for key, width in (("n", 4), ("mu", 8), ("notes", 20)):
                table.add_column(key, key=key, width=width)
            for i in range(30):
                table.add_row(f"{i:>4}", f"{0.0085 + i / 1e5:8.5f}", "a note [kg]", key=str(i))
            await pilot.pause(0.2)
            kept = len(table._row_renderable_cache)
            size = table.virtual_size
            # DataTable's own measure, for the same rows: the same size
            super(ResultsTable, table)._update_dimensions(list(table.rows))
            return kept, size, table.virtual_size

    kept, ours, datatable = asyncio.run(run())
    assert kept == 0
    assert ours == datatable and ours.width == 4 + 8 + 20 and ours.height == 31


def test_the_table_extends_its_rows_in_order_as_datatable_lists_them():
    """The rows in order and the row on each line, extended as rows are added (DataTable
    built both again after every update: 2000 rows at descent 2000), are DataTable's own,
    also after a clear, a sort, a removal and with a row two lines high."""
    from textual.widgets import DataTable

    def same(table: ResultsTable) -> None:
        assert table.ordered_rows == DataTable.ordered_rows.fget(table)
        assert table._y_offsets == DataTable._y_offsets.fget(table)
        for i in range(table.row_count + 1):
            assert table._get_row_region(i) == DataTable._get_row_region(table, i)

    async def run() -> None:
        app = OneTable()
        async with app.run_test(size=(80, 24)) as pilot:
            table = _five_rows(app.query_one(ResultsTable))
            first = table.ordered_rows
            same(table)
            table.add_row("   5", " 0.00500", key="5")
            table.update_cell("2", "mu", " 0.00999")
            await pilot.pause(0.1)
            assert table.ordered_rows is first  # extended, not built again
            same(table)
            table.sort("mu", reverse=True)
            same(table)
            table.remove_row("3")
            same(table)
            table.add_row("   6", " 0.00600", key="6", height=2)
            same(table)
            table.clear()
            table.add_row("   7", " 0.00700", key="7")
            await pilot.pause(0.1)
            same(table)

    asyncio.run(run())


def descent_lines(demo_track, k: int) -> list[bytes]:
    """The ALGE lines of descent ``k`` on the demo run, one per photocell."""
    import numpy as np

    from station.model.physics import Conditions, Params, StraightRun
    from station.timing.wireformats import format_alge

    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
        .t
    )
    t0 = 10 * 3600 * 10**6 + k * 60_000_000
    return [
        (format_alge(f"C{i}", t0 + round(ti * 1e6), k * 10 + i) + "\r").encode()
        for i, ti in enumerate(t)
    ]


@pytest.mark.parametrize("fit_s", [0.15, 0.8])
def test_a_descents_last_impulse_is_drawn_with_its_fit(tmp_path, demo_track, monkeypatch, fit_s):
    """The last impulse's log line, the counts and the progress wait for the descent's fit and
    are drawn in its frame (a frame of their own came first, while the fit was computed);
    when the fit takes longer than HOLD_S they are drawn without it."""
    import time

    from station.session.acquisition import Acquisition
    from station.session.analysis import Analyser
    from station.session.config import load_config
    from station.session.rawlog import Chunk
    from station.ui import app as app_module
    from station.ui.app import StationApp
    from tests.timing_helpers import write_config

    fit = Analyser.run

    def slow_fit(self, job):  # a fit on a busy laptop
        time.sleep(fit_s)
        return fit(self, job)

    monkeypatch.setattr(Analyser, "run", slow_fit)
    monkeypatch.setattr(Acquisition, "start_serial", lambda self, serial=None: None)
    frames: list[tuple[float, bool, int]] = []  # when, the last impulse in the log, rows

    class Watched(StationApp):
        CSS_PATH = os.path.join(os.path.dirname(app_module.__file__), "station.tcss")

        def _display(self, screen, renderable) -> None:
            super()._display(screen, renderable)
            if renderable is not None and self.columns:
                log = self.main.query_one("#log")
                shown = any(last in line.text for line in log.lines)
                frames.append((time.monotonic(), shown, self.main.query_one("#table").row_count))

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    app = Watched(cfg, mode="live")
    lines = descent_lines(demo_track, 1)
    last = f"C{len(lines) - 1}→"  # the last photocell's channel, in the log

    async def run() -> float:
        async with app.run_test(size=(120, 40)) as pilot:
            await wait_for(pilot, lambda: app.acq is not None)
            for line in lines[:-1]:
                app.acq.receive(Chunk(time.time(), line))
            await wait_for(pilot, lambda: app._fit_imminent())
            await pilot.pause(0.2)
            start = time.monotonic()
            app.acq.receive(Chunk(time.time(), lines[-1]))
            await wait_for(pilot, lambda: any(shown for _, shown, _ in frames))
            await wait_for(pilot, lambda: app.main.query_one("#table").row_count == 1)
            await pilot.pause(0.2)
            return start

    start = asyncio.run(run())
    first = next(f for f in frames if f[1])  # the first frame with the last impulse in it
    if fit_s < app_module.HOLD_S:
        assert first[2] == 1, "the last impulse was drawn before its fit"
    else:  # no fit within HOLD_S: drawn without it, not held until it came
        assert first[2] == 0 and first[0] - start < fit_s


@pytest.mark.parametrize("where", ["handler", "quitting"])
def test_python_gets_its_collector_back_when_the_app_raises(tmp_path, monkeypatch, where):
    """An exception inside the app (a handler), or while it quits (a port that raises as it
    closes): Python's thresholds come back, and the objects frozen at the start are again
    the collector's (a process that goes on, as a test run does, collected none of them)."""
    from station.session.acquisition import Acquisition
    from station.session.config import load_config
    from station.ui.app import StationApp
    from tests.timing_helpers import write_config

    saved = gc.get_threshold()
    monkeypatch.setattr(Acquisition, "start_serial", lambda self, serial=None: None)
    if where == "quitting":

        def unplugged(self) -> None:
            raise OSError("the port went away as it closed")

        monkeypatch.setattr(Acquisition, "stop", unplugged)
    app = StationApp(load_config(str(write_config(tmp_path, "loop://"))), mode="live")

    def boom() -> None:
        raise RuntimeError("a handler failed")

    async def run() -> None:
        async with app.run_test(size=(80, 24)) as pilot:
            await wait_for(pilot, lambda: app.acq is not None)
            assert gc.get_threshold()[2] == NEVER
            if where == "handler":
                app.call_later(boom)
            await pilot.pause(0.3)

    with pytest.raises((RuntimeError, OSError)):
        asyncio.run(run())
    assert gc.get_threshold() == saved
    assert gc.get_freeze_count() == 0, "the app's objects stayed out of the collector's reach"


def test_a_new_theme_is_drawn_in_the_table():
    """A theme that changes the cursor's and the header's colours but not the table's
    background: the table draws it (its kept lines were keyed by the background alone)."""
    import dataclasses

    from textual.theme import BUILTIN_THEMES

    async def run() -> tuple:
        app = OneTable()
        dark = BUILTIN_THEMES["textual-dark"]
        app.register_theme(
            dataclasses.replace(dark, name="red", primary="#ff0000", accent="#00ff00")
        )
        async with app.run_test(size=(80, 24)) as pilot:
            table = _five_rows(app.query_one(ResultsTable))
            await pilot.pause(0.2)

            def lines() -> list:
                return [list(table.render_line(y)) for y in range(4)]

            before = lines()
            app.theme = "red"
            await pilot.pause(0.3)
            shown = lines()
            table._clear_caches()  # everything drawn afresh
            return before, shown, lines()

    before, shown, fresh = asyncio.run(run())
    assert fresh != before  # the theme does change what the table shows
    assert shown == fresh


def test_a_warning_comes_after_the_impulses_held_before_it(tmp_path, demo_track, monkeypatch):
    """A warning that arrives while a descent's last impulse waits for its fit is written
    after that impulse in the log, not before it: the log is read top to bottom."""
    import time

    from station.session.acquisition import Acquisition
    from station.session.analysis import Analyser
    from station.session.config import load_config
    from station.session.rawlog import Chunk
    from station.ui.app import StationApp
    from station.ui.messages import AcquisitionWarning
    from tests.timing_helpers import write_config

    fit = Analyser.run

    def slow_fit(self, job):
        time.sleep(0.15)
        return fit(self, job)

    monkeypatch.setattr(Analyser, "run", slow_fit)
    monkeypatch.setattr(Acquisition, "start_serial", lambda self, serial=None: None)
    app = StationApp(load_config(str(write_config(tmp_path, "loop://"))), mode="live")
    lines = descent_lines(demo_track, 1)
    last = f"C{len(lines) - 1}→"

    async def run() -> list[str]:
        async with app.run_test(size=(120, 40)) as pilot:
            await wait_for(pilot, lambda: app.acq is not None)
            for line in lines[:-1]:
                app.acq.receive(Chunk(time.time(), line))
            await wait_for(pilot, lambda: app._fit_imminent())
            app.acq.receive(Chunk(time.time(), lines[-1]))
            app.post_message(AcquisitionWarning("something after the last impulse"))
            await wait_for(pilot, lambda: app.main.query_one("#table").row_count == 1)
            await pilot.pause(0.4)
            return [line.text for line in app.main.query_one("#log").lines]

    log = asyncio.run(run())
    impulse = next(i for i, text in enumerate(log) if last in text)
    warning = next(i for i, text in enumerate(log) if "something after" in text)
    assert impulse < warning, log


def _five_rows(table):
    """The results table with two fixed-width columns and five rows (the table tests')."""
    table.add_column("n", key="n", width=4)
    table.add_column("mu", key="mu", width=8)
    for i in range(5):
        table.add_row(f"{i:>4}", f"{i / 1e3:8.5f}", key=str(i))
    return table
