"""The day report: one self-contained HTML page, one picture per section."""

from __future__ import annotations

import base64
import re
import subprocess
import sys

import pytest

from tests.session_helpers import make_session

FIGURE_SECTIONS = ["track", "descents", "timeline", "comparison"]


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
    assert list(sections) == [*FIGURE_SECTIONS, "provenance"]
    for name in FIGURE_SECTIONS:
        assert sections[name].count("<img ") == 1, name
    assert "<img " not in sections["provenance"]
    cmp = sections["comparison"]
    assert "pair A / blue" in cmp and "pair B / blue" in cmp
    assert "Δμ vs pair B / blue" in cmp  # the reference, named by its beginning
    assert "descent 6: marked invalid: edged after PC6" in cmp
    assert "Drift of μ" in cmp
    prov = sections["provenance"]
    for text in ("sha256", "station version", "config.yaml of the session", "72 impulses",
                 "invalid: edged after PC6"):  # fmt: skip
        assert text in prov, text
    assert len(re.findall(r"<tr><td>\d+</td><td>2026-02-02 ", prov)) == 8  # every descent


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
    assert r.returncode == 2 and "not a session directory" in r.stderr


def test_the_command_line_does_not_load_matplotlib():
    code = "import sys, station.cli.main; print('matplotlib' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_aborted_and_unfitted_descents_have_their_panel(tmp_path, demo_track):
    """Drawn from the report's own records: an aborted descent (a walk-through) and a descent
    not fitted show their status instead of bars, and the page is still whole."""
    import dataclasses

    from station.report.day_report import DayData, build_day_report, descent_views
    from station.session import store
    from station.session.acquisition import replay

    session = make_session(tmp_path, order="AB")
    run = replay(str(session), store.load_session_config(str(session)))
    views = descent_views(run.results())
    assert [v.item for v in views] == ["pair A / blue", "pair B / blue"]
    assert all(v.good and len(v.residuals_ms) == 9 for v in views)
    aborted = dataclasses.replace(
        views[0], number=3, status="aborted", descent_status="aborted", estimates={}, ci90={},
        residuals_ms={}, rms_ms=None, speed_x=None, speed_v=None, photocells_used=1,
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
