"""The real Textual app: driven by Pilot against the simulated timer and replays, snapshots of
the main screen, and ``station demo`` in tmux read off the captured pane."""

from __future__ import annotations

import asyncio
import datetime as dt
import functools
import inspect
import os
import shutil
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest
from textual.binding import Binding

from station.model.physics import Conditions, Params, StraightRun
from station.session.config import load_config
from station.timing.wireformats import format_alge
from station.ui.app import StationApp
from station.ui.screens import ComparisonScreen, HelpScreen, MetadataScreen, ReasonScreen
from tests.conftest import station_cmd
from tests.timing_helpers import SimFreeze, raw_lines, start_sim, write_config


def run_async(fn):
    """Run an async test with asyncio.run (no pytest plugin needed); fixtures pass through."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        return asyncio.run(fn(*args, **kwargs))

    wrapper.__signature__ = inspect.signature(fn)  # type: ignore[attr-defined]
    return wrapper


async def wait_for(pilot, condition, timeout: float = 40.0) -> None:
    end = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < end, "timed out waiting for the UI"
        await pilot.pause(0.1)


async def wait_for_screen(pilot, app, screen_type) -> None:
    """Until a dialog is up: a key pressed before it is would go to the screen below."""
    await wait_for(pilot, lambda: isinstance(app.screen, screen_type))


async def wait_for_replay(pilot, app) -> None:
    """Until the replay has finished and the UI shows the comparison of the whole day. The fit
    worker compares again whenever its queue runs empty: a comparison of part of the day can
    come before "replay finished", and the whole day's after it."""
    from tests.session_helpers import live_comparison_text

    await wait_for(pilot, lambda: "replay finished" in app.connection)
    whole_day = live_comparison_text(app.acq.track, app.acq.results())
    await wait_for(pilot, lambda: app.comparison_text == whole_day)


def steady_cursors(app) -> None:
    """Text fields stop blinking (the cursor stays on): a snapshot cannot depend on the blink
    phase the screenshot happens to catch."""
    from textual.widgets import Input

    for field in app.screen.query(Input):
        field.cursor_blink = False


def make_capture(path, demo_track) -> None:
    """A deterministic day: a clean descent, one with a missed photocell, a walk-through,
    and one that stops being timed after three photocells (too few for a fit)."""
    xs = np.array([pc.x for pc in demo_track.photocells])
    t = (
        StraightRun(demo_track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079))
        .t
    )
    lines, n = [], 0
    starts = [10 * 3600, 10 * 3600 + 60, 10 * 3600 + 120, 10 * 3600 + 180]
    for k, start in enumerate(starts):
        for i, ti in enumerate(t):
            if (k == 1 and i == 4) or (k == 2 and i > 0) or (k == 3 and i > 2):
                continue
            n += 1
            lines.append(format_alge(f"C{i}", int((start + ti) * 1e6), n) + "\r")
    path.write_text("".join(lines), newline="")


def replay_app(tmp_path, demo_track) -> StationApp:
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    cfg = load_config(str(write_config(tmp_path, "loop://")))
    return StationApp(cfg, mode="replay", source=str(cap), date=dt.date(2026, 2, 2))


@pytest.mark.slow  # a simulated timer on a pty, in real time
@run_async
async def test_live_ui_against_the_simulated_timer(tmp_path, run_station):
    sim, port, truth = start_sim(
        tmp_path, "--speed", "10", "--first-after", "2", "--hold", "1", "--descents", "3",
        "--seed", "21",
    )  # fmt: skip
    cfg = load_config(str(write_config(tmp_path, port)))
    session = tmp_path / "session"
    app = StationApp(cfg, mode="live", session_dir=str(session))
    # the timer stops after descent 1 until the metadata is entered: on a busy machine the
    # form took so long that descent 3 had started and the metadata applied to none of them
    freeze = SimFreeze(sim, session, 9)
    try:
        async with app.run_test(size=(100, 30)) as pilot:
            await wait_for(pilot, lambda: len(app.results) >= 1)
            table = app.main.query_one("#table")
            await wait_for(pilot, lambda: table.row_count >= 1)
            assert "timer connected" in str(app.main.query_one("#status").render())
            result = str(app.main.query_one("#result").render())
            assert "μ" in result and "CdA" in result and "ok" in result
            assert "PC9" in str(app.main.query_one("#residuals").render())
            # metadata for the following descents
            await pilot.press("m")
            await wait_for_screen(pilot, app, MetadataScreen)
            app.screen.query_one("#f_ski").value = "pair 7"
            app.screen.query_one("#f_wax").value = "LF blue"
            await pilot.press("enter")
            await wait_for(pilot, lambda: app.metadata_from is not None)
            start = app.metadata_from
            freeze.wait()
            assert raw_lines(session) < 18  # descent 3 has not started: it gets the metadata
            freeze.thaw()
            # mark descent 1 invalid with a reason (selected once descent 2 is in: the cursor
            # follows new descents only while it is on the last row)
            await wait_for(pilot, lambda: table.row_count >= 2)
            table.move_cursor(row=0)
            await pilot.press("i")
            await wait_for_screen(pilot, app, ReasonScreen)
            await pilot.press(*"fell at PC7", "enter")
            await wait_for(pilot, lambda: app.results[1].row.invalid_reason == "fell at PC7")
            await wait_for(pilot, lambda: "INV" in str(table.get_cell("1", "status")))
            # refit it with velocity-dependent friction
            await pilot.press("v")
            await wait_for(pilot, lambda: app.results[1].row.model == "velocity")
            await wait_for(pilot, lambda: len(app.results) >= 3, timeout=60)
            await pilot.press("e")
            await pilot.pause(0.3)
    finally:
        freeze.thaw()
        sim.wait(timeout=30)
    df = pd.read_csv(session / "results.csv", comment="#")
    assert df.loc[0, "invalid_reason"] == "fell at PC7" and df.loc[0, "model"] == "velocity"
    later = df[df["descent"] >= start]
    assert (
        len(later) >= 1 and (later["ski"] == "pair 7").all() and (later["wax"] == "LF blue").all()
    )
    # the session, annotations included, replays to the same CSV
    out = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == (session / "results.csv").read_bytes()


@pytest.mark.slow  # a simulated timer on a pty, in real time
@run_async
async def test_ui_shows_an_unplugged_timer_and_goes_on(tmp_path):
    sim, port, _ = start_sim(
        tmp_path, "--speed", "20", "--first-after", "2", "--hold", "1", "--descents", "2",
        "--interval", "80", "--disconnect-after", "1", "--disconnect-s", "1", "--seed", "2",
    )  # fmt: skip
    cfg = load_config(str(write_config(tmp_path, port)))
    app = StationApp(cfg, mode="live", session_dir=str(tmp_path / "s"))
    # what the UI showed at each change of the status line: polling the screen can miss the
    # second offline altogether on a busy machine, "disconnected" and "connected" both handled
    # between two looks
    seen: list[tuple[bool, str]] = []
    update_status = app._update_status

    def recording() -> None:
        update_status()
        seen.append((app.has_class("offline"), str(app.main.query_one("#status").render())))

    app._update_status = recording  # type: ignore[method-assign]
    try:
        async with app.run_test(size=(80, 24)) as pilot:
            await wait_for(pilot, lambda: any(offline for offline, _ in seen))
            shown = [status for offline, status in seen if offline]
            assert all("TIMER DISCONNECTED" in status for status in shown), shown
            await wait_for(pilot, lambda: len(app.results) >= 2, timeout=60)
            assert not app.has_class("offline")
    finally:
        sim.wait(timeout=30)


@run_async
async def test_failed_fits_and_aborted_descents_show_their_status(tmp_path, demo_track):
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(160, 40)) as pilot:
        await wait_for(pilot, lambda: len(app.results) == 4)
        await pilot.pause(0.3)
        table = app.main.query_one("#table")
        statuses = [str(table.get_cell(str(n), "status")).strip() for n in range(1, 5)]
        assert statuses == ["ok", "ok", "aborted", "too-few-photocells"]
        # the flags have a column of their own; "notes" are the engineer's notes
        assert "missed PC5" in str(table.get_cell("2", "flags"))
        assert str(table.get_cell("2", "notes")).strip() == ""


@pytest.mark.parametrize("size", [(80, 24), (100, 30), (200, 50)])
def test_main_screen_snapshot(snap_compare, tmp_path, demo_track, size):
    """The laptop at the run (80×24), a larger terminal and a full screen (the plots grow);
    descent 2 selected, so the panel shows its flags."""
    app = replay_app(tmp_path, demo_track)

    async def finished(pilot) -> None:
        await wait_for_replay(pilot, app)
        await pilot.pause(0.3)
        app.clear_notifications()  # the toast's time-out is not part of the picture
        await pilot.press("up", "up")
        await wait_for(pilot, lambda: app.shown == 2)  # the panel follows the selection
        await pilot.pause(0.5)

    assert snap_compare(app, terminal_size=size, run_before=finished)


@pytest.mark.parametrize("key", ["question_mark", "m", "c"])
def test_dialog_snapshot_at_80x24(snap_compare, tmp_path, demo_track, key):
    app = replay_app(tmp_path, demo_track)

    async def opened(pilot) -> None:
        await wait_for_replay(pilot, app)
        assert "joint fit" in app.comparison_text
        app.clear_notifications()
        await pilot.press(key)
        await wait_for(pilot, lambda: app.screen is not app.main)  # the dialog is up
        steady_cursors(app)
        await pilot.pause(0.5)  # and drawn, on a loaded machine too
        await pilot.wait_for_scheduled_animations()

    assert snap_compare(app, terminal_size=(80, 24), run_before=opened)


@pytest.mark.slow  # station demo in tmux, in real time
@pytest.mark.skipif(not shutil.which("tmux") and not os.environ.get("CI"), reason="needs tmux")
def test_station_demo_in_tmux_shows_a_fitted_row(tmp_path):
    assert shutil.which("tmux"), "tmux must be installed in CI (.ci/run installs it)"
    name = f"station-demo-{os.getpid()}"
    cmd = " ".join([*station_cmd(), "demo", "--speed", "4", "--seed", "5", "--session-dir",
                    str(tmp_path / "demo"), "; sleep 30"])  # fmt: skip
    subprocess.run(["tmux", "kill-session", "-t", name], capture_output=True)
    subprocess.run(
        ["tmux", "new-session", "-d", "-s", name, "-x", "80", "-y", "24", cmd], check=True
    )
    try:
        end = time.monotonic() + 60
        screen = ""
        while time.monotonic() < end:
            screen = subprocess.run(
                ["tmux", "capture-pane", "-p", "-t", name], capture_output=True, text=True
            ).stdout
            rows = [ln for ln in screen.splitlines() if ln.strip().startswith("1 ")]
            if rows and " ok " in rows[0] + " ":
                break
            time.sleep(0.5)
        rows = [ln for ln in screen.splitlines() if ln.strip().startswith("1 ")]
        assert rows, screen
        assert "demo pair A" in rows[0] and "ok" in rows[0], screen
        assert "timer connected" in screen
        after = rows[0].split("demo pair A")[1].split()
        mu = float(next(tok for tok in after if tok[:1].isdigit()))  # after the wax
        assert 0.006 < mu < 0.011
        # q: the UI is gone and the session's place said within a second (measured ~0.4 s;
        # the bound leaves room for a busy 2-core machine)
        t0 = time.monotonic()
        subprocess.run(["tmux", "send-keys", "-t", name, "q"], check=True)
        while time.monotonic() - t0 < 10:
            screen = subprocess.run(
                ["tmux", "capture-pane", "-p", "-J", "-t", name], capture_output=True, text=True
            ).stdout  # -J: the message's wrapped lines joined
            if "session saved in" in screen:
                break
            time.sleep(0.02)
        quit_s = time.monotonic() - t0
        assert "session saved in" in screen and str(tmp_path / "demo") in screen, screen
        assert quit_s < 2.0, quit_s
    finally:
        subprocess.run(["tmux", "kill-session", "-t", name], capture_output=True)
    assert (tmp_path / "demo" / "raw.jsonl").exists()
    assert (tmp_path / "demo" / "results.csv").exists()


@run_async
async def test_comparison_view_updates_after_each_descent(tmp_path, demo_track):
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for_replay(pilot, app)
        await pilot.press("c")
        await wait_for_screen(pilot, app, ComparisonScreen)
        text = str(app.screen.query_one("#comparison_text").render())
        assert "joint fit of 2 descents" in text and "(no item)" in text
        assert "descent 3 left out: aborted" in text
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is app.main)


@run_async
async def test_comparison_dims_the_screen_behind_as_textual_does(tmp_path, demo_track):
    """The comparison's dimmed background, tinted line by line and kept (DimmedScreen), is
    Textual's own (BackgroundScreen) segment for segment, also after the screen behind it
    changed (a line kept by what it showed before must not come back)."""
    from textual._context import visible_screen_stack
    from textual.renderables.background_screen import BackgroundScreen
    from textual.visual import RichVisual, Visual

    from station.ui.screens import DimmedScreen

    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for_replay(pilot, app)
        await pilot.press("c")
        await wait_for_screen(pilot, app, ComparisonScreen)
        await pilot.pause(0.3)
        screen = app.screen

        def both() -> tuple[list, list]:
            visible_screen_stack.set(app._background_screens)
            ours = screen.render()
            assert isinstance(ours, DimmedScreen)
            textual = RichVisual(screen, BackgroundScreen(ours.base, ours.color))
            w, h = screen.size
            return [Visual.to_strips(screen, v, w, h, screen.visual_style) for v in (ours, textual)]

        ours, textual = both()
        assert len(ours) == 40 and ours == textual
        app.main.query_one("#log").write("a line behind the dialog")
        app.main.query_one("#status").update("the status changed behind the dialog")
        await pilot.pause(0.3)
        again, textual_again = both()
        assert again == textual_again and again != ours


@run_async
async def test_quitting_mid_descent_ends_it_as_record_does(tmp_path, run_station):
    """``q`` while a skier is on the run: the descent is ended as Ctrl-C ends it in ``station
    record`` (fitted with what it has, "the recording ended"), so the session replays to the
    same CSV (before, the UI left it out)."""
    sim, port, _ = start_sim(
        tmp_path, "--speed", "5", "--first-after", "2", "--hold", "1", "--descents", "3",
        "--seed", "3",
    )  # fmt: skip
    cfg = load_config(str(write_config(tmp_path, port)))
    session = tmp_path / "session"
    app = StationApp(cfg, mode="live", session_dir=str(session))
    # the skier is held on the run after four photocells: on a busy machine the UI, lagging
    # behind the timer, could show four while the descent had already finished
    freeze = SimFreeze(sim, session, 9 + 4)
    try:
        async with app.run_test(size=(100, 30)) as pilot:

            def on_the_run() -> bool:
                p = app.progress
                return p is not None and p.number == 2 and len(p.passed) >= 4

            await wait_for(pilot, on_the_run, timeout=60)
            freeze.wait()
            assert raw_lines(session) < 18 and len(app.progress.passed) < 9
            await pilot.press("q")
    finally:
        freeze.thaw()
        sim.terminate()
        sim.wait(timeout=30)
    df = pd.read_csv(session / "results.csv", comment="#")
    assert list(df["descent_status"]) == ["complete", "incomplete"]
    assert "the recording ended" in df.loc[1, "flags"] and df.loc[1, "status"] != "error"
    out = tmp_path / "replay.csv"
    r = run_station("replay", session, "--csv", out)
    assert r.returncode == 0, r.stderr
    assert out.read_bytes() == (session / "results.csv").read_bytes()


@run_async
async def test_a_fit_that_raises_shows_as_error_and_the_replay_goes_on(
    tmp_path, demo_track, monkeypatch
):
    import station.session.analysis as analysis

    real, calls = analysis.fit_descent, {"n": 0}

    def fit(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 1:
            raise np.linalg.LinAlgError("Singular matrix")
        return real(*args, **kwargs)

    monkeypatch.setattr(analysis, "fit_descent", fit)
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(160, 40)) as pilot:
        await wait_for(pilot, lambda: "replay finished" in app.connection)
        await pilot.pause(0.3)
        table = app.main.query_one("#table")
        statuses = [str(table.get_cell(str(n), "status")).strip() for n in range(1, 5)]
        assert statuses == ["error", "ok", "aborted", "too-few-photocells"]
        assert "fit failed: LinAlgError: Singular matrix" in str(table.get_cell("1", "flags"))
        table.move_cursor(row=0)
        await wait_for(pilot, lambda: app.shown == 1)  # the highlight is a message of its own
        assert "error: fit failed" in str(app.main.query_one("#result").render())


@run_async
async def test_a_results_csv_that_cannot_be_written_shows_in_the_status_line(
    tmp_path, demo_track, monkeypatch
):
    import station.session.results as results
    from station.session.rawlog import Chunk

    def full(rows, path, header):
        raise OSError(28, "No space left on device")

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    app = StationApp(cfg, mode="live", session_dir=str(tmp_path / "s"))
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    async with app.run_test(size=(160, 40)) as pilot:
        await wait_for(pilot, lambda: app.acq is not None)
        monkeypatch.setattr(results, "write_results", full)
        monkeypatch.setattr(results, "append_results", lambda *_a: full(None, None, None))
        # host times of now: the reader's idle tick ends a descent whose time-out passed, and
        # by a host time months back, descent 1 timed out between two of its lines
        now = time.time()
        for i, line in enumerate(cap.read_bytes().split(b"\r")[:9]):  # descent 1
            app.acq.receive(Chunk(now + i * 0.01, line + b"\r"))
        # the worker writes the CSV before it hands the result over: wait for both
        await wait_for(pilot, lambda: "No space left" in app.problem and 1 in app.results)
        await pilot.pause(0.1)
        status = str(app.main.query_one("#status").render())
        assert "cannot write" in status and "raw log keeps recording" in app.problem
        status = app.main.query_one("#table").get_cell("1", "status")
        assert str(status).strip() == "ok"  # the result is shown


# ----------------------------------------------------------------------------- one descent


def _panel(app) -> str:
    return str(app.main.query_one("#result").render())


@run_async
async def test_the_panel_shows_the_selected_row_and_keys_work_at_once(tmp_path, demo_track):
    """One notion of "the descent": ↑/↓ work without Tab (the table has the focus), the panel
    shows the selected row, and i acts on the descent the panel shows."""
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: "replay finished" in app.connection)
        await pilot.pause(0.2)
        table = app.main.query_one("#table")
        assert app.focused is table
        # the cursor followed the new descents: the last row is selected and shown
        assert table.cursor_row == 3 and app.shown == 4
        assert _panel(app).startswith("descent 4 ")
        await pilot.press("up", "up")
        await wait_for(pilot, lambda: app.shown == 2)  # the highlight is a message of its own
        assert table.cursor_row == 1 and _panel(app).startswith("descent 2 ")
        await pilot.press("i")
        await wait_for_screen(pilot, app, ReasonScreen)
        assert app.screen.number == 2
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is app.main)  # v would be typed as the reason
        await pilot.press("v")  # refits the descent shown, and the panel shows its μ1
        await wait_for(pilot, lambda: app.results[2].row.model == "velocity")
        await pilot.pause(0.2)
        assert app.shown == 2 and "velocity model\nμ1 " in _panel(app)  # μ1 with its interval


@run_async
async def test_a_selection_is_kept_when_a_new_descent_arrives(tmp_path, demo_track):
    """The cursor follows new descents only while it is on the last row; the panel does not
    jump to a new descent while the engineer looks at an older one."""
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    app = StationApp(cfg, mode="live", session_dir=str(tmp_path / "s"))
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    lines = cap.read_bytes().split(b"\r")
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.acq is not None)

        now = time.time()  # the reader's idle tick ends a descent whose time-out passed

        def feed(part):
            for i, line in enumerate(part):
                app.acq.receive(Chunk(now + i * 0.01, line + b"\r"))

        feed(lines[:9])  # descent 1
        await wait_for(pilot, lambda: 1 in app.results)
        feed(lines[9:17])  # descent 2 (a photocell missed)
        await wait_for(pilot, lambda: 2 in app.results)
        await pilot.pause(0.2)
        assert app.shown == 2  # on the last row: followed
        await pilot.press("up")
        await wait_for(pilot, lambda: app.shown == 1)  # the highlight is a message of its own
        feed(lines[17:])  # descents 3 and 4
        app.acq.end_of_input()
        await wait_for(pilot, lambda: len(app.results) >= 4)
        await pilot.pause(0.2)
        table = app.main.query_one("#table")
        assert table.cursor_row == 0 and app.shown == 1
        assert _panel(app).startswith("descent 1 ")


@run_async
async def test_the_table_scrolls_to_new_descents_at_80x24(tmp_path, demo_track):
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    app = StationApp(cfg, mode="live", session_dir=str(tmp_path / "s"))
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    one = cap.read_bytes().split(b"\r")[:9]  # descent 1: nine photocells
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.acq is not None)
        now = time.time()  # the reader's idle tick ends a descent whose time-out passed
        for k in range(12):  # twelve descents, a minute apart
            for i, line in enumerate(one):
                shifted = line.replace(b"10:", b"%02d:" % (10 + k), 1) if k else line
                app.acq.receive(Chunk(now + 60 * k + i, shifted + b"\r"))
        app.acq.end_of_input()
        await wait_for(pilot, lambda: len(app.results) >= 12)
        table = app.main.query_one("#table")
        assert table.cursor_row == table.row_count - 1 == 11
        assert app.shown == 12

        def last_row_in_sight() -> bool:  # scrolling to the cursor waits for a refresh
            visible = table.scrollable_content_region.height - 1  # the header row
            return table.scroll_y + visible >= 12 > table.scroll_y

        await wait_for(pilot, last_row_in_sight)


# ----------------------------------------------------------------------------- 80x24


def test_no_number_is_ever_cut_in_the_table():
    from station.ui.app import _num, table_columns

    for width in (80, 100, 120, 129, 130, 200):
        cols = table_columns(width)
        assert sum(c.width + 1 for c in cols) <= width, width
        keys = {c.key for c in cols}
        assert {"n", "start", "ski", "wax", "mu", "cda", "v0", "rms", "status", "notes"} <= keys
    assert _num(0.22437, 4, 6) == "0.2244"
    assert _num(12.3456, 4, 6) == "12.346"  # fewer decimals, never "12.34" cut from "12.3456"
    assert _num(1234567.0, 4, 6) == "1e+06"
    assert _num(-1.5e12, 2, 4) == "####"
    assert _num(None, 2, 4) == "—" and _num(float("nan"), 2, 4) == "—"


# ----------------------------------------------------------------------------- no terminal


@pytest.mark.parametrize("command", ["demo", "live", "replay"])
def test_ui_commands_refuse_without_a_terminal(run_station, tmp_path, demo_track, command):
    """``station demo </dev/null >file``: one line, exit 2, nothing written, no session (a
    wrong config, port or source is said first: that needs no terminal)."""
    if command == "live":
        args = ["live", "--config", write_config(tmp_path, "loop://")]
    elif command == "replay":
        make_capture(tmp_path / "capture.txt", demo_track)
        args = ["replay", tmp_path / "capture.txt", "--ui", "--config",
                write_config(tmp_path, "loop://")]  # fmt: skip
    else:
        args = ["demo"]
    r = run_station(*args, cwd=tmp_path)  # pytest's stdin and captured stdout: no terminal
    assert r.returncode == 2
    assert r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "is not a terminal" in lines[0], r.stderr
    assert not (tmp_path / "sessions").exists()


def test_station_demo_without_a_terminal_refuses_as_a_process(tmp_path):
    out = tmp_path / "out.txt"
    with open(out, "w") as fh:
        r = subprocess.run(
            [*station_cmd(), "demo"], stdin=subprocess.DEVNULL, stdout=fh,
            stderr=subprocess.PIPE, text=True, timeout=60, cwd=tmp_path,
        )  # fmt: skip
    assert r.returncode == 2 and out.read_text() == ""
    assert r.stderr.count("\n") == 1 and "standard input is not a terminal" in r.stderr


# ----------------------------------------------------------------------------- dialogs


def _inside(widget, size) -> bool:
    r = widget.region
    return r.width > 0 and r.height > 0 and r.right <= size[0] and r.bottom <= size[1]


@pytest.mark.parametrize("size", [(80, 24), (100, 30)])
@run_async
async def test_dialogs_fit_the_terminal(tmp_path, demo_track, size):
    """Help and the metadata form need no scrolling at 80×24; the Close button of the
    comparison is in sight however long the text."""
    app = replay_app(tmp_path, demo_track)

    async def laid_out(screen_type, button: str) -> None:
        """The dialog is up and laid out: before its first layout every region is empty and
        nothing scrolls, so the checks below would pass for any dialog."""
        await wait_for_screen(pilot, app, screen_type)
        await wait_for(pilot, lambda: _inside(app.screen.query_one(button), size))
        await pilot.pause()

    async with app.run_test(size=size) as pilot:
        await wait_for_replay(pilot, app)
        assert "joint fit" in app.comparison_text
        await pilot.press("question_mark")
        await laid_out(HelpScreen, "#close")
        body = app.screen.query_one(".dialog-body")
        assert body.max_scroll_y == 0 and body.max_scroll_x == 0
        assert _inside(app.screen.query_one("#close"), size)
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is app.main)
        await pilot.press("m")
        await laid_out(MetadataScreen, "#save")
        form = app.screen.query_one("#form")
        assert form.max_scroll_y == 0
        assert _inside(app.screen.query_one("#save"), size)
        assert _inside(app.screen.query_one("#f_notes"), size)
        await pilot.press("escape")
        await wait_for(pilot, lambda: app.screen is app.main)
        await pilot.press("c")
        await laid_out(ComparisonScreen, "#close")
        assert _inside(app.screen.query_one("#close"), size)
        assert "joint fit" in str(app.screen.query_one("#comparison_text").render())
        await pilot.click("#close")
        await wait_for(pilot, lambda: app.screen is app.main)


@run_async
async def test_metadata_form_names_the_next_descent_and_saves_only_changes(tmp_path, demo_track):
    """While descent 1 runs the form is for descent 2 on (as the toast then says); a field
    left as it was pre-filled (the demo's next pair of skis) is not written again."""
    from station.session.rawlog import Chunk
    from station.session.store import read_annotations

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    session = tmp_path / "s"
    app = StationApp(cfg, mode="live", session_dir=str(session))
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    lines = cap.read_bytes().split(b"\r")
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.acq is not None)
        app.acq.add_metadata({"ski": "pair B"}, from_descent=2)  # as the demo's rotation does
        now = time.time()  # the reader's idle tick ends a descent whose time-out passed
        for i, line in enumerate(lines[:3]):  # descent 1 is on the run
            app.acq.receive(Chunk(now + i * 0.01, line + b"\r"))
        await wait_for(pilot, lambda: app.progress is not None and app.progress.number == 1)
        await pilot.press("m")
        await wait_for_screen(pilot, app, MetadataScreen)
        title = str(app.screen.query_one("#title").render())
        assert "from descent 2 on" in title
        assert app.screen.query_one("#f_ski").value == "pair B"  # pre-filled
        app.screen.query_one("#f_wax").value = "LF blue"
        await pilot.press("enter")
        await wait_for(pilot, lambda: app.metadata_from is not None)
        assert app.metadata_from == 2
    last = read_annotations(str(session))[-1]
    assert last.from_descent == 2
    assert last.values.values() == {"wax": "LF blue"}  # the pre-filled ski not written again


@pytest.mark.parametrize("size", [(80, 24), (100, 30), (200, 50)])
@run_async
async def test_plots_fit_their_boxes_and_grow_with_the_terminal(tmp_path, demo_track, size):
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=size) as pilot:
        await wait_for(pilot, lambda: "replay finished" in app.connection)
        await pilot.press("up", "up")  # descent 2: a fit with a speed profile
        await wait_for(pilot, lambda: app.shown == 2)  # the highlight is a message of its own
        await pilot.pause(0.5)
        for wid in ("#residuals", "#speed"):
            box = app.main.query_one(wid)
            lines = str(box.render()).splitlines()
            assert len(lines) == app.plot_rows <= box.content_region.height, wid
            assert max(map(len, lines)) <= box.content_region.width, wid
        speed = str(app.main.query_one("#speed").render()).splitlines()
        assert speed[-1].rstrip().endswith(" 366") and "x [m]" in speed[-1]
        # the table keeps at least six rows at 24 lines; at 50 the plots take what is left
        assert app.main.query_one("#table").content_region.height >= 6
        assert app.plot_rows == (6 if size[1] <= 30 else 16)


def test_no_footer_key_repeats_its_own_letter():
    """The footer showed "v Refit v"."""
    for b in StationApp.BINDINGS:
        if isinstance(b, Binding):
            assert b.key not in b.description.lower().split(), b


@run_async
async def test_a_replay_names_its_source_and_export_counts_the_rows_written(
    tmp_path, demo_track, monkeypatch
):
    """The replay's title lacked what it replays; ``e`` counted the rows in the table, and
    said 5 exported when the file had 6 (a fit on its way to the table is written too)."""
    monkeypatch.chdir(tmp_path)  # a capture's export goes to the working folder
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(100, 30)) as pilot:
        await wait_for_replay(pilot, app)
        assert app.sub_title == "replay · capture.txt"
        shown = dict(app.results)
        app.results.pop(max(app.results))  # as if its message were still on its way
        app.clear_notifications()
        await pilot.press("e")
        await wait_for(pilot, lambda: bool(app._notifications))
        said = " ".join(str(n.message) for n in app._notifications)
        app.results.update(shown)
    written = tmp_path / "capture-results.csv"
    rows = [x for x in written.read_text().splitlines() if x and not x.startswith(("#", '"'))]
    assert len(rows) == len(shown) == 4
    assert said.startswith(f"4 descents exported to {written}"), said


@run_async
async def test_a_ski_typed_in_the_demo_stops_its_rotation(tmp_path, demo_track):
    """The demo's rotation set the next pair whenever a descent started, over the ski the
    engineer had just typed."""
    from station.session.rawlog import Chunk

    cfg = load_config(str(write_config(tmp_path, "loop://")))
    no_timer = [sys.executable, "-c", "pass"]  # the descents are fed below
    app = StationApp(cfg, mode="demo", session_dir=str(tmp_path / "s"), sim_command=no_timer,
                     demo_skis=["demo pair A", "demo pair B", "demo pair C"])  # fmt: skip
    cap = tmp_path / "capture.txt"
    make_capture(cap, demo_track)
    lines = cap.read_bytes().split(b"\r")[:17]  # descents 1 and 2 (one photocell missed)
    async with app.run_test(size=(100, 30)) as pilot:
        await wait_for(pilot, lambda: app.acq is not None)
        await pilot.press("m")
        await wait_for_screen(pilot, app, MetadataScreen)
        assert app.screen.query_one("#f_ski").value == "demo pair A"
        app.screen.query_one("#f_ski").value = "my own pair"
        await pilot.press("enter")
        await wait_for(pilot, lambda: app.metadata_from is not None)
        said = " ".join(str(n.message) for n in app._notifications)
        assert "the demo's rotation of skis stops" in said
        now = time.time()
        for i, line in enumerate(lines):
            app.acq.receive(Chunk(now + i * 0.01, line + b"\r"))
        await wait_for(pilot, lambda: len(app.results) == 2)
        assert [app.acq.day.metadata_for(n).ski for n in (1, 2, 3)] == ["my own pair"] * 3
