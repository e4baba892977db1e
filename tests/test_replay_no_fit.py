"""``station replay … --no-fit``: the descents, their crossing times and the impulses' fates of a
capture or a session, without a fit: the same descents and times the fitted replay has."""

from __future__ import annotations

import csv
import io

from tests.session_helpers import make_session


def test_no_fit_gives_the_fitted_replays_descents_times_and_events(tmp_path, run_station):
    session = make_session(tmp_path, order="ABAB")
    fitted = run_station("replay", session, "--times", tmp_path / "t.csv",
                         "--events", tmp_path / "e.csv")  # fmt: skip
    assert fitted.returncode == 0, fitted.stderr
    quick = run_station("replay", session, "--no-fit", "--times", tmp_path / "tq.csv",
                        "--events", tmp_path / "eq.csv")  # fmt: skip
    assert quick.returncode == 0, quick.stderr
    lines = quick.stdout.splitlines()
    assert len(lines) == 4 and all(" · complete · 9 photocells, PC1 " in x for x in lines)
    assert lines[0].startswith("descent 1 · complete")
    assert quick.stderr.splitlines()[0].endswith("4 descents (4 complete); not fitted")
    assert "36 crossing times" in quick.stderr
    # the same events, and the same times (the fitted replay's residuals aside)
    assert (tmp_path / "eq.csv").read_text() == (tmp_path / "e.csv").read_text()
    times = list(csv.reader(io.StringIO((tmp_path / "t.csv").read_text())))
    quick_times = list(csv.reader(io.StringIO((tmp_path / "tq.csv").read_text())))
    assert [r[:6] for r in quick_times] == [r[:6] for r in times]
    assert {r[6] for r in quick_times[1:]} == {""}
    assert any(r[6] for r in times[1:])  # the fitted replay has residuals there


def test_no_fit_writes_its_times_to_standard_output_alone(tmp_path, run_station):
    session = make_session(tmp_path, order="AB")
    out = run_station("replay", session, "--no-fit", "--times", "-")
    assert out.returncode == 0, out.stderr
    rows = list(csv.reader(io.StringIO(out.stdout)))
    assert rows[0][:3] == ["descent", "bib", "photocell"] and len(rows) == 1 + 18


def test_no_fit_refuses_what_needs_a_fit_in_one_line(tmp_path, run_station):
    session = make_session(tmp_path, order="AB")
    for option in (["--csv", str(tmp_path / "r.csv")], ["--ui"]):
        out = run_station("replay", session, "--no-fit", *option)
        assert out.returncode == 2
        assert out.stderr.count("\n") == 1 and "leave out --no-fit" in out.stderr
        assert not (tmp_path / "r.csv").exists()
