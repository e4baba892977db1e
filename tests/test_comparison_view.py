"""The comparison is what a test day is run for: at 80×24 every number of it is in sight
without sideways scrolling (a new-user trial found Δμ cut after its first digits)."""

from __future__ import annotations

from textual.containers import ScrollableContainer

from station.ui.screens import ComparisonScreen
from tests.session_helpers import make_session
from tests.test_replay_marks import session_replay_app
from tests.test_ui import run_async, wait_for, wait_for_replay, wait_for_screen


@run_async
async def test_the_comparison_needs_no_sideways_scrolling_at_80x24(tmp_path):
    session = make_session(tmp_path, order="ABBAABBA")
    app = session_replay_app(session)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for_replay(pilot, app)
        assert max(len(line) for line in app.comparison_text.splitlines()) > 80  # it must wrap
        await pilot.press("c")
        await wait_for_screen(pilot, app, ComparisonScreen)
        body = app.screen.query_one(ScrollableContainer)
        await wait_for(pilot, lambda: body.size.width > 0)
        await pilot.pause(0.2)
        assert body.virtual_size.width <= body.size.width  # nothing off to the right
        assert body.max_scroll_x == 0


@run_async
async def test_the_result_panel_is_never_cut_between_80_and_200_columns(tmp_path, demo_track):
    """μ and CdA with their intervals share a line: the log of impulses beside the panel
    appears only where that line still fits (at 110 columns CdA's interval was cut)."""
    from station.ui.app import NARROW
    from tests.test_ui import replay_app

    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for_replay(pilot, app)
        app.main.query_one("#table").move_cursor(row=0)  # descent 1: fitted, with intervals
        await wait_for(pilot, lambda: app.shown == 1)
        for width in (80, 100, 110, 120, NARROW - 1, NARROW, 160, 200):
            await pilot.resize_terminal(width, 30)
            await pilot.pause(0.2)
            panel = app.main.query_one("#result")
            await wait_for(pilot, lambda p=panel, w=width: p.size.width > 0 and app.size.width == w)
            text = str(panel.render())
            mu_cda = next(line for line in text.splitlines() if line.startswith("μ "))
            assert "CdA" in mu_cda and mu_cda.endswith("]"), text  # the panel shows an interval
            assert len(mu_cda) <= panel.content_region.width, (width, mu_cda)


@run_async
async def test_the_comparison_runs_in_a_process_of_its_own_and_survives_its_death(tmp_path):
    """The day's joint fit takes seconds at 2000 descents: in the UI's process it held the
    interpreter against the next descent's fit and its drawing (issue 19). It runs in a
    process of its own; if that process dies, the UI says so once and the next comparison
    starts a new one with the whole day."""
    import os

    from tests.session_helpers import live_comparison_text

    session = make_session(tmp_path, order="ABBAABBA")
    app = session_replay_app(session)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for_replay(pilot, app)  # the whole day's comparison, shown or not
        proc = app.acq.comparer._proc
        assert proc is not None and proc.pid != os.getpid() and proc.poll() is None
        whole_day = app.comparison_text
        proc.kill()
        proc.wait()
        app.comparison_text = ""
        app.acq.comparer.update(app.results[1])  # a change: compared again (the replay ended)
        await wait_for(pilot, lambda: "comparison failed" in app.problem)
        app.acq.comparer.update(app.results[2])
        await wait_for(pilot, lambda: app.comparison_text == whole_day)
        assert app.acq.comparer._proc is not None and app.acq.comparer._proc.pid != proc.pid
        assert whole_day == live_comparison_text(app.acq.track, app.acq.results())
    assert app.acq.comparer._proc is None  # quitting ended it
    assert proc.poll() is not None


@run_async
async def test_table_cells_are_text_not_markup(tmp_path, demo_track):
    """The table draws its cells itself (station.ui.table): a note with brackets is shown as
    typed, not taken for Rich markup, and a row replaced in place shows its new cells."""
    from station.ui.table import ResultsTable
    from tests.test_ui import replay_app

    app = replay_app(tmp_path, demo_track)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for_replay(pilot, app)
        table = app.main.query_one("#table", ResultsTable)
        table.update_cell("1", "notes", " mass [kg] checked [b]twice[/b]")
        await pilot.pause(0.2)
        row = table.get_row_index("1")
        y = row + table.header_height - int(table.scroll_y)
        line = table.render_line(y).text
        assert "mass [kg] checked [b]twice[/b]" in line, line
