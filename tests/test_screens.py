"""The metadata form as a user types into it: a decimal comma is a decimal mark, text in a
number field is refused next to the field (seen at 80×24 and 100×30), and only what was
changed is saved."""

from __future__ import annotations

import asyncio
import time
from pathlib import Path

import pytest
from textual.app import App

from station.ui.screens import MetadataScreen

CSS = Path(__file__).resolve().parents[1] / "station" / "ui" / "station.tcss"
CURRENT = {"ski": "demo pair A", "mass_kg": 88.0, "pressure_hpa": 835.0}


class FormApp(App):
    """The form on the station's own style sheet, without the rest of the UI."""

    CSS_PATH = str(CSS)

    def __init__(self) -> None:
        super().__init__()
        self.result: object = "not dismissed"

    def on_mount(self) -> None:
        self.push_screen(MetadataScreen(dict(CURRENT), 3), self._done)

    def _done(self, values) -> None:
        self.result = values


async def _until(pilot, condition, timeout: float = 40.0) -> None:
    """Poll ``condition`` while the app runs; a fixed pause stood in for "the form has caught
    up", which a busy machine does not honour. After ``timeout`` the test's checks say what
    was missing."""
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        await pilot.pause(0.05)


def _answered(app) -> bool:
    """Enter has had its effect: the form was dismissed, or it refused (its error line says
    so; a field's own message shows while typing already) and the message is drawn."""
    if app.result != "not dismissed":
        return True
    if not isinstance(app.screen, MetadataScreen):
        return False
    if not str(app.screen.query_one("#error").render()):
        return False
    subtitle = str(getattr(app.screen.focused, "border_subtitle", "") or "")
    return bool(subtitle) and subtitle.replace(" ", "&#160;") in app.export_screenshot()


async def _fill(size, entries: dict[str, str]):
    app = FormApp()
    async with app.run_test(size=size) as pilot:
        await _until(pilot, lambda: isinstance(app.screen, MetadataScreen))
        for key, text in entries.items():
            field = app.screen.query_one(f"#f_{key}")
            field.focus()
            field.value = ""
            await pilot.press(*text)
        await pilot.press("enter")
        await _until(pilot, lambda: _answered(app))
        shot = app.export_screenshot() if app.result == "not dismissed" else ""
        focused = app.screen.focused
        info = None
        if focused is not None:
            info = (focused.id, focused.border_subtitle, focused.region, app.screen.region)
        return app.result, info, shot


def test_a_decimal_comma_is_the_decimal_mark_and_only_changes_are_saved():
    """72,5 was stored as 725 (the number field dropped the comma); pre-filled fields saved
    as they were overrode later entries."""
    result, _, _ = asyncio.run(_fill((100, 30), {"mass_kg": "72,5", "wax": "LF blue"}))
    assert result == {"mass_kg": 72.5, "wax": "LF blue"}


@pytest.mark.parametrize("size", [(80, 24), (100, 30)])
@pytest.mark.parametrize(
    ("key", "text", "message"),
    [("mass_kg", "7x", "not a number"), ("wind_from_deg", "400", "must lie between 0 and 360"),
     ("humidity_pct", "1,5.0", "point or comma, not both"),
     ("pressure_hpa", "nan", "not a number")],
)  # fmt: skip
def test_a_wrong_number_is_refused_next_to_its_field(size, key, text, message):
    result, info, shot = asyncio.run(_fill(size, {key: text}))
    assert result == "not dismissed"  # Enter did not save, and did not silently drop it
    fid, subtitle, region, screen = info
    assert fid == f"f_{key}" and subtitle == message
    # the field, with its message in its border, is on screen: not below Save/Cancel
    assert screen.contains_region(region)
    assert message.replace(" ", "&#160;") in shot  # drawn whole on the screen, not only stored
