"""The day report: one self-contained HTML page, one picture per section."""

from __future__ import annotations

import base64
import html
import re
import subprocess
import sys

import numpy as np
import pytest

from tests.session_helpers import make_session

#: the answer first (the verdict, then μ and CdA over the day), then the details
SECTIONS = ["verdict", "timeline", "comparison", "track", "descents", "provenance"]
FIGURE_SECTIONS = ["timeline", "comparison", "track", "descents"]


def _sections(page: str) -> dict[str, str]:
    return dict(re.findall(r'<section id="([a-z]+)">(.*?)</section>', page, flags=re.S))


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    from tests.conftest import station_cmd

    tmp = tmp_path_factory.mktemp("report")
    session = make_session(tmp, order="ABBAABBA")
    for args in (["--descents", "6", "--invalid", "edged after PC6"],
                 ["--descents", "3", "--notes", "<script>alert(1)</script> & more"]):  # fmt: skip
        r = subprocess.run([*station_cmd(), "annotate", str(session), *args],
                           capture_output=True, text=True)  # fmt: skip
        assert r.returncode == 0, r.stderr
    out = tmp / "out"  # made by the command
    cmd = [*station_cmd(), "report", str(session), "--out", str(out), "--reference", "pair b"]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    path = out / "session.html"
    assert r.stdout.strip() == str(path)
    return path.read_text(encoding="utf-8")


def test_the_page_is_self_contained(report):
    assert report.startswith("<!DOCTYPE html>")
    assert not re.search(r"https?://|<link|<script|<iframe|url\(|src=\"(?!data:)", report)
    images = re.findall(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"', report)
    assert len(images) == len(FIGURE_SECTIONS)
    for b64 in images:
        png = base64.b64decode(b64, validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000  # a real picture


def test_one_picture_per_section_and_what_they_show(report):
    sections = _sections(report)
    assert list(sections) == SECTIONS
    for name in FIGURE_SECTIONS:
        assert sections[name].count("<img ") == 1, name
    assert "<img " not in sections["provenance"]
    cmp = sections["comparison"]
    assert "pair A / blue" in cmp and "pair B / blue" in cmp
    assert "Δμ vs pair B / blue" in cmp  # the reference, named by its beginning
    # the reference's own row says so, not a P(faster) of an item against itself
    ref_row = re.search(r"<tr><td>\d</td><td>pair B / blue</td>.*?</tr>", cmp).group(0)
    assert ref_row.count("<td>reference</td>") == 3, ref_row
    assert "descent 6: marked invalid: edged after PC6" in cmp
    assert "Drift of μ" in cmp
    prov = sections["provenance"]
    for text in ("sha256", "station version", "config.yaml of the session", "72 impulses",
                 "invalid: edged after PC6"):  # fmt: skip
        assert text in prov, text
    assert len(re.findall(r"<tr><td>\d+</td><td>2026-02-02 ", prov)) == 8  # every descent


def test_the_comparison_describes_the_model_it_fitted(report):
    """The day model has a posture random effect and a time offset per descent: the page says
    so and gives the scatter, as the terminal does (it once said "one CdA per skier" only)."""
    cmp = _sections(report)["comparison"].split("<details>")[0]  # not the terminal's copy
    assert "varies by the posture scatter" in cmp and "time offset" in cmp
    assert re.search(r"Posture scatter \(CdA between descents of a skier\): \d+\.\d\d %", cmp)


def test_user_text_is_escaped(report):
    prov = _sections(report)["provenance"]
    assert "&lt;script&gt;alert(1)&lt;/script&gt; &amp; more" in prov


def test_a_day_without_a_comparison_still_gets_its_page(tmp_path, run_station):
    session = make_session(tmp_path, order="A", annotate=False)
    assert run_station("annotate", session, "--descents", "1", "--invalid", "fell").returncode == 0
    r = run_station("report", session, "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "o" / "session.html").read_text()
    sections = _sections(page)
    assert "No comparison: no valid descent" in sections["comparison"]
    assert "<img " not in sections["comparison"]
    assert sections["track"].count("<img ") == 1


def test_report_output_folder_errors(tmp_path, run_station):
    session = make_session(tmp_path, order="A", annotate=False)
    (tmp_path / "file").write_text("")
    for out, expect in ((tmp_path / "file", "is a file, not a folder"),
                        (tmp_path / "no" / "such", "does not exist")):  # fmt: skip
        r = run_station("report", session, "--out", out)
        assert r.returncode == 2 and expect in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1
    r = run_station("report", tmp_path / "nosession", "--out", tmp_path / "o")
    assert r.returncode == 2 and "no such session folder" in r.stderr


def test_the_command_line_does_not_load_matplotlib():
    code = "import sys, station.cli.main; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_aborted_and_unfitted_descents_have_their_panel(tmp_path, demo_track):
    """Drawn from the report's own records: an aborted descent (a walk-through) and a descent
    not fitted show their status instead of bars, and the page is still whole."""
    import dataclasses

    from station.model.estimate import MISSING
    from station.report.day_data import DayData, descent_views
    from station.report.day_report import build_day_report
    from station.session import folder as session_folder
    from station.session.runs import replay

    session = make_session(tmp_path, order="AB")
    run = replay(str(session), session_folder.load_session_config(str(session)))
    views = descent_views(run.results())
    assert [v.item for v in views] == ["pair A / blue", "pair B / blue"]
    assert all(v.good and len(v.residuals_ms) == 9 for v in views)
    aborted = dataclasses.replace(
        views[0], number=3, status="aborted", descent_status="aborted", mu=MISSING, cda=MISSING,
        v0=MISSING, residuals_ms={}, rms_ms=None, speed_x=None, speed_v=None, photocells_used=1,
    )  # fmt: skip
    page = build_day_report(DayData(str(session), run.day.track, [*views, aborted]))
    sections = _sections(page)
    assert sections["descents"].count("<img ") == 1
    assert "2 descents (2 ok and valid)" in sections["descents"]
    assert "<td>3</td>" in sections["provenance"] and "aborted" in sections["provenance"]


def test_a_day_with_a_cleared_start_gets_its_page(tmp_path, run_station):
    """A start the operator cleared at the timer leaves a descent with no time at all: the
    report drew its start from its first time and ended in a traceback."""
    from tests.timing_helpers import write_config

    cfg = write_config(tmp_path, "/dev/null", "alge", {"C0": "PC1", "C1": "PC9"})
    cap = tmp_path / "day.txt"
    cap.write_text(
        " 0001 C0  09:00:00.0000 00\rc0001 C0  09:00:00.0000 00\r"
        " 0002 C0  09:05:00.0000 00\r 0002 C1  09:05:30.0000 00\r",
        newline="",
    )
    session = tmp_path / "s"
    assert run_station("import", cap, "--config", cfg, "--session-dir", session).returncode == 0
    r = run_station("report", session, "--out", tmp_path / "rep")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "rep" / "s.html").exists()


def test_the_verdict_comes_first_in_words_and_numbers(report):
    """Which is faster, Δμ with its interval, the time over the run, how sure, how many
    descents, decided or not: before any picture, and the drift's reference time named."""
    sections = _sections(report)
    verdict = sections["verdict"]
    assert report.index('<section id="verdict">') < report.index("<img ")
    head = re.search(r"<li class='(\w+)'>(.*?)</li>", verdict, flags=re.S)
    assert head.group(1) == "decided"
    text = re.sub(r"<[^>]+>", "", head.group(2))
    assert text.startswith("pair A / blue glides better than pair B / blue by Δμ "), text
    m = re.search(r"by Δμ (\d\.\d{5}) \[\+(\d\.\d{5}), \+(\d\.\d{5})\] \(90 %\), "
                  r"(\d+\.\d) ms over the run at v0 \d\.\d m/s; "
                  r"P\(pair A / blue faster\) (> 0\.999|0\.\d{3}); "
                  r"4 descents of pair A / blue, 3 of pair B / blue", text)  # fmt: skip
    assert m, text
    dmu, lo, hi, ms = (float(m.group(k)) for k in (1, 2, 3, 4))
    assert 0 < lo < dmu < hi and 0.0008 < dmu < 0.0012 and ms > 10  # simulated 0.0010
    # the decision's own interval (widened for the looks), as station compare prints it
    m = re.search(r"decided: the interval widened for a look after every descent, "
                  r"\[\+(0\.\d{5}), \+(0\.\d{5})\], excludes 0", text)  # fmt: skip
    assert m, text
    assert float(m.group(1)) < lo and hi < float(m.group(2))
    # the drift's reference: the compared descents' mean start (10:00 … 10:35 but descent 6)
    assert "μ of each item at 10:16, the compared descents' mean start" in html.unescape(verdict)
    assert "each item's μ is its value at 10:16" in html.unescape(sections["timeline"])


def test_an_item_with_one_valid_descent_is_not_comparable(tmp_path, run_station):
    """It crashed the report (TypeError on the missing interval); it is a line of the
    verdict, of the table and of the picture."""
    session = make_session(tmp_path, order="AAB")
    r = run_station("report", session, "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    sections = _sections((tmp_path / "o" / "session.html").read_text())
    verdict = re.sub(r"<[^>]+>", "", sections["verdict"])
    assert "pair B / blue against pair A / blue: not comparable (1 valid descent)" in verdict
    assert "not comparable (1 valid descent)" in sections["comparison"]
    assert sections["comparison"].count("<img ") == 1


def test_time_of_day_ticks_fall_on_whole_minutes():
    from station.report.day_figures import MAX_TICKS, minute_ticks

    rng = np.random.default_rng(3)
    for _ in range(500):
        h0 = rng.uniform(0, 30)
        h1 = h0 + rng.choice([rng.uniform(2 / 60, 0.2), rng.uniform(0.2, 12)])
        ticks = minute_ticks(h0, h1)
        minutes = np.array(ticks) * 60
        assert 2 <= len(ticks) <= MAX_TICKS, (h0, h1, ticks)
        assert np.allclose(minutes, np.round(minutes), atol=1e-6)
        steps = np.diff(np.round(minutes))
        assert len(set(steps)) == 1 and steps[0] in (1, 2, 5, 10, 15, 20, 30, 60, 120, 180)
        assert h0 - 1e-9 <= ticks[0] and ticks[-1] <= h1 + 1e-9


def test_the_time_axis_labels_every_tick_on_a_whole_minute(tmp_path):
    """The picture itself: its ticks are the minute ticks, every one labelled hh:mm."""
    from station.report.day_data import descent_views
    from station.report.day_figures import item_colours, time_of_day_axes
    from station.session import folder as session_folder
    from station.session.runs import replay

    session = make_session(tmp_path, order="ABBA", interval_s=437.0)
    run = replay(str(session), session_folder.load_session_config(str(session)))
    views = descent_views(run.results())
    fig = time_of_day_axes(views, item_colours(["pair A / blue", "pair B / blue"]))
    ax = fig.axes[1]
    ticks = ax.get_xticks()
    labels = [ax.xaxis.get_major_formatter()(t) for t in ticks]
    assert len(ticks) >= 3
    assert np.allclose(ticks * 60, np.round(ticks * 60))
    assert all(re.fullmatch(r"\d\d:\d\d", lab) for lab in labels), labels
    assert len(set(labels)) == len(labels)


def test_the_out_folder_is_made_as_the_help_says(tmp_path, run_station):
    """The help said "made if missing"; it is made when its parent exists, and says so."""
    r = run_station("report", "--help")
    assert "made if missing, in a folder that exists" in " ".join(r.stdout.split())
    session = make_session(tmp_path, order="A", annotate=False)
    r = run_station("report", session, "--out", tmp_path / "new")
    assert r.returncode == 0 and (tmp_path / "new" / "session.html").exists()
    assert r.stderr == "1 descent; open it in a browser\n"


def test_names_drawn_in_pictures_are_never_read_as_math():
    """matplotlib reads $…$ as math: an item named "wax $x_1$" was drawn as x₁, and a name
    with a bad formula between dollars would end the report in a parse error."""
    from matplotlib.text import Text

    from station.report.day_figures import plain

    for name in ("wax $x_1$", "pair $\\frac$ b", "$5 and $10"):
        shown, is_math = Text(text=plain(name))._preprocess_math(plain(name))
        assert not is_math and shown == name, (name, shown)


def test_the_page_names_the_session_by_its_folder_not_its_absolute_path(tmp_path, run_station):
    """The page is mailed: the session's metadata gave /home/…/sessions/NAME, a path of this
    machine that means nothing to the reader (and tells what it need not)."""
    session = make_session(tmp_path, order="AB", annotate=False)
    r = run_station("report", session, "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "o" / "session.html").read_text()
    meta = _sections(page)["provenance"]
    assert f"<td>session</td><td>{session.name}</td>" in meta.replace("\n", ""), meta[:2000]
    assert str(tmp_path) not in page
