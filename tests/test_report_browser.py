"""The day report as its reader sees it: opened in headless Chromium (tests/browser.py) at
1280×800 with the network closed. The verdict is on the first screen, every picture loads,
the page asks for nothing beyond itself, and test items named like markup are shown as text.
A screenshot of the first screen is kept as a test artefact (``STATION_TEST_ARTIFACTS``, by
default ``tmp/artifacts`` in the checkout).

Without a browser these tests are skipped, except in CI (``CI`` set), where a missing browser
is a failure: .ci/run installs Debian's ``chromium``.
"""

from __future__ import annotations

import os
import re
import struct
import subprocess
from pathlib import Path

import pytest

from tests.browser import Browser, find_browser
from tests.session_helpers import make_session

pytestmark = pytest.mark.slow  # a report and a browser: ~40 s on a busy 2-core machine

ROOT = Path(__file__).resolve().parents[1]
#: a test item named like markup, with both kinds of quote (and like matplotlib's math)
EVIL = "<script>alert(\"A\")</script> 'quoted' <b>A</b> &amp; $x_1$"


def artifacts() -> Path:
    folder = Path(os.environ.get("STATION_TEST_ARTIFACTS") or ROOT / "tmp" / "artifacts")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture(scope="module")
def browser():
    exe = find_browser()
    if exe is None:
        if os.environ.get("CI"):  # as tests/conftest.py: in CI a missing tool fails
            pytest.fail("no chromium in CI: .ci/run installs it (apt-get install chromium)")
        pytest.skip("no chromium here (apt-get install chromium)")
    b = Browser(exe, 1280, 800)
    yield b
    b.close()


@pytest.fixture(scope="module")
def page(browser, tmp_path_factory):
    from tests.conftest import station_cmd

    tmp = tmp_path_factory.mktemp("browser")
    session = make_session(tmp, order="ABBAABBA")
    r = subprocess.run([*station_cmd(), "annotate", str(session), "--descents", "1,4,5,8",
                        "--ski", EVIL], capture_output=True, text=True)  # fmt: skip
    assert r.returncode == 0, r.stderr
    r = subprocess.run([*station_cmd(), "report", str(session), "--out", str(tmp / "out")],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr
    p = browser.open(tmp / "out" / "session.html")
    p.screenshot(artifacts() / "day_report_first_screen.png")
    return p


def test_the_verdict_is_on_the_first_screen(page):
    rect = page.evaluate(
        "(() => { const r = document.querySelector('#verdict ul.verdicts').getBoundingClientRect();"
        " return [r.top, r.bottom, r.left, r.right, window.innerWidth, window.innerHeight]; })()"
    )
    top, bottom, left, right, width, height = rect
    assert (width, height) == (1280, 800)
    assert 0 <= top < bottom <= height and 0 <= left < right <= width, rect
    first = page.evaluate("document.querySelector('#verdict li').innerText")
    assert first.startswith(f"{EVIL} / blue glides better than pair B / blue"), first
    assert "decided: the interval widened for a look after every descent, [+0." in first
    # the first picture is μ and CdA over the day, right after the verdict
    img = page.evaluate("document.images[0].closest('section').id")
    assert img == "timeline"


def test_every_picture_loads(page):
    sizes = page.evaluate(
        "Promise.all([...document.images].map(i => i.decode().then("
        "() => [i.closest('section').id, i.naturalWidth, i.naturalHeight])))"
    )
    assert [s[0] for s in sizes] == ["timeline", "comparison", "track", "descents"]
    assert all(w > 500 and h > 150 for _id, w, h in sizes), sizes
    # the residuals are folded: opened, the picture is there and drawn at the page's width
    shown = page.evaluate(
        "(() => { const d = document.querySelector('#descents details');"
        " const i = d.querySelector('img'); const closed = i.checkVisibility(); d.open = true;"
        " return [closed, i.checkVisibility(), i.getBoundingClientRect().width]; })()"
    )
    assert shown[0] is False and shown[1] is True and shown[2] > 1000, shown


def test_the_page_never_scrolls_sideways(page):
    """A table of long item names scrolls inside its section; the page itself keeps to the
    window (the descents' table of a day with long names pushed it 3 px wider at 1200 px, and
    more at longer names)."""
    wide = page.evaluate("document.documentElement.scrollWidth")
    assert wide <= page.evaluate("window.innerWidth"), wide


def test_the_page_needs_no_network(page):
    assert page.requests == [] and page.failed == []
    assert page.evaluate("performance.getEntriesByType('resource').length") == 0
    assert page.evaluate("document.querySelectorAll('script, link, iframe, object').length") == 0


def test_item_names_with_markup_are_shown_as_text(page, browser):
    text = page.evaluate("document.body.innerText")
    name = f"{EVIL} / blue"  # its literal text, quotes, tags and the entity as typed
    assert f"{name} glides better than pair B / blue by Δμ" in text
    assert f"P({name} faster)" in text
    assert page.evaluate("document.querySelectorAll('b b, section b > b').length") == 0
    assert not [e for e in browser.events if e.get("method") == "Page.javascriptDialogOpening"]


def test_a_screenshot_of_the_first_screen_is_kept(page):
    shot = artifacts() / "day_report_first_screen.png"
    data = shot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert struct.unpack(">II", data[16:24]) == (1280, 800)
    assert re.search(rb"IDAT", data) and len(data) > 20_000


@pytest.fixture(scope="module")
def season_page(browser, tmp_path_factory):
    """The season report of three days (A–B, B–C, A–C) with ski A named like markup."""
    import datetime as dt

    from tests.conftest import station_cmd
    from tests.season_helpers import make_day

    base = tmp_path_factory.mktemp("season-browser")
    names = {"A": EVIL, "B": "SB", "C": "SC"}
    days = []
    for d, (a, b) in enumerate(["AB", "BC", "AC"]):
        days.append(make_day(
            base, f"day{d}", dt.date(2026, 1, 10 + d), (a + b + b + a) * 2,
            {x: 0.012 + {"A": 0.0, "B": 0.001, "C": -0.0006}[x] for x in (a, b)},
            items={x: {"ski": names[x], "wax": "blue"} for x in (a, b)},
            conditions={"snow_temperature_c": -10.0 + 3 * d}, seed=d,
        ))  # fmt: skip
    store = str(base / "season.db")
    for args in (["season", "add", *map(str, days)], ["season", "report", "--out", str(base)]):
        r = subprocess.run([*station_cmd(), *args, "--store", store], capture_output=True,
                           text=True, timeout=600)  # fmt: skip
        assert r.returncode == 0, r.stderr
    p = browser.open(base / "season.html")
    p.screenshot(artifacts() / "season_report_first_screen.png")
    return p


def test_the_season_report_in_the_browser(season_page):
    """Its answer (a verdict per item, then the ranking) on the first screen, every picture
    loading, no network, the markup of an item's name shown as text."""
    verdict = season_page.evaluate(
        "(() => { const r = document.querySelector('#verdict ul.verdicts').getBoundingClientRect();"
        " return [r.top, r.bottom]; })()"
    )
    assert 0 <= verdict[0] < verdict[1] <= 800, verdict
    first = season_page.evaluate("document.querySelector('#verdict li').innerText")
    assert "Δμ" in first and "days" in first and ("decided" in first or "comparable" in first)
    top = season_page.evaluate(
        "(() => { const r = document.querySelector('#ranking table').getBoundingClientRect();"
        " return [r.top, r.bottom]; })()"
    )
    assert 0 <= top[0] < top[1] <= 800, top
    sizes = season_page.evaluate(
        "Promise.all([...document.images].map(i => i.decode().then("
        "() => [i.naturalWidth, i.naturalHeight])))"
    )
    assert len(sizes) == 2 and all(w > 300 and h > 150 for w, h in sizes), sizes
    assert season_page.requests == [] and season_page.failed == []
    assert season_page.evaluate("document.querySelectorAll('script, b b').length") == 0
    assert f"{EVIL} / blue" in season_page.evaluate("document.body.innerText")
