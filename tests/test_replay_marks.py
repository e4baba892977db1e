"""What the engineer enters while replaying a day in the UI is saved in the replayed session, as
``station annotate`` saves it; in the replay of a plain capture it is said at once to be for
this replay only. Before, both were accepted, shown, and lost without a word at quit."""

from __future__ import annotations

import datetime as dt

from station.cli.tui import save_kept
from station.session import folder as session_folder
from station.session.records import InvalidMark
from station.ui.app import StationApp
from station.ui.screens import ReasonScreen
from tests.session_helpers import make_session, read_json_lines
from tests.test_ui import replay_app, run_async, wait_for, wait_for_replay, wait_for_screen


def session_replay_app(session) -> StationApp:
    """The UI replaying a recorded session folder (not a capture file), with its own config."""
    cfg = session_folder.load_session_config(str(session))
    return StationApp(cfg, mode="replay", source=str(session), date=dt.date(2026, 2, 2))


async def _notified(app, pilot) -> str:
    """The notifications on screen, once there is one."""
    await wait_for(pilot, lambda: bool(app._notifications))
    return " ".join(str(n.message) for n in app._notifications)


async def _mark_invalid(app, pilot, reason: str) -> None:
    table = app.main.query_one("#table")
    table.move_cursor(row=0)
    await wait_for(pilot, lambda: app.shown == 1)
    await pilot.press("i")
    await wait_for_screen(pilot, app, ReasonScreen)
    await pilot.press(*reason, "enter")
    await wait_for(pilot, lambda: app.results[1].row.invalid)


@run_async
async def test_a_mark_made_while_replaying_a_session_is_saved_in_it(tmp_path):
    session = make_session(tmp_path, order="ABAB")
    before = (session / session_folder.ANNOTATIONS).read_text()
    app = session_replay_app(session)
    async with app.run_test(size=(100, 30)) as pilot:
        await wait_for_replay(pilot, app)
        await _mark_invalid(app, pilot, "wrong mass")
        said = await _notified(app, pilot)
        assert "saved in the session when you quit" in said
    assert [type(a) for a in app.kept] == [InvalidMark] and app.kept[0].t is not None
    assert (
        session / session_folder.ANNOTATIONS
    ).read_text() == before  # saved at the end, not before

    assert save_kept(app) == 0
    records = read_json_lines(session / session_folder.ANNOTATIONS)
    assert records[-1]["type"] == "invalid" and records[-1]["reason"] == "wrong mass"
    csv_text = (session / session_folder.RESULTS).read_text()
    first = next(line for line in csv_text.splitlines() if line.startswith("1,"))
    assert "wrong mass" in first  # results.csv rewritten with the mark


@run_async
async def test_a_mark_in_the_replay_of_a_capture_says_it_is_not_saved(tmp_path, demo_track):
    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(100, 30)) as pilot:
        await wait_for_replay(pilot, app)
        await _mark_invalid(app, pilot, "test")
        said = await _notified(app, pilot)
        assert "this replay only" in said
    assert app.kept == []
    assert save_kept(app) == 0


def test_the_printed_lines_say_invalid_and_updated(run_station, tmp_path):
    """Headless, a descent marked invalid printed as plain "ok", and a refit printed the same
    line again with nothing to say why."""
    from station.cli.console import PrintListener
    from station.session.recorded_session import RecordedSession

    session = make_session(tmp_path, order="AB")
    assert run_station("annotate", session, "--descents", "2", "--invalid", "fell").returncode == 0
    r = run_station("replay", session)
    assert r.returncode == 0, r.stderr
    out = r.stdout + r.stderr
    line2 = next(x for x in out.splitlines() if x.startswith("descent   2"))
    assert line2.endswith("INVALID: fell")
    assert "1 marked invalid" in out
    line1 = next(x for x in out.splitlines() if x.startswith("descent   1"))
    assert "INVALID" not in line1

    acq = RecordedSession(str(session)).run()
    printed: list[str] = []
    listener = PrintListener(printed.append)
    first = acq.results()[0]
    listener.result(first)
    listener.result(first)
    assert "updated" not in printed[0] and printed[1].endswith(
        "(updated: an annotation or a refit)"
    )


@run_async
async def test_the_metadata_form_saved_unchanged_records_nothing(tmp_path):
    from station.ui.screens import MetadataScreen

    session = make_session(tmp_path, order="AB")
    app = session_replay_app(session)
    async with app.run_test(size=(100, 30)) as pilot:
        await wait_for_replay(pilot, app)
        await pilot.press("m")
        await wait_for_screen(pilot, app, MetadataScreen)
        await pilot.press("enter")
        await wait_for(pilot, lambda: app.screen is app.main)
        said = await _notified(app, pilot)
        assert "nothing saved" in said
    assert app.kept == []
