"""The comparison is what a test day is run for: at 80×24 every number of it is in sight
without sideways scrolling (a new-user trial found Δμ cut after its first digits)."""

from __future__ import annotations

import datetime as dt

from textual.containers import ScrollableContainer

from station.session import store
from station.ui.app import StationApp
from station.ui.screens import ComparisonScreen
from tests.session_helpers import make_session
from tests.test_ui import run_async, wait_for, wait_for_replay, wait_for_screen


@run_async
async def test_the_comparison_needs_no_sideways_scrolling_at_80x24(tmp_path):
    session = make_session(tmp_path, order="ABBAABBA")
    cfg = store.load_session_config(str(session))
    app = StationApp(cfg, mode="replay", source=str(session), date=dt.date(2026, 2, 2))
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
