"""Output paths checked before any work (one line, exit 2; ``-`` is standard output), options
spelt out, descents a session does not have refused, and ``station sessions``."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import pandas as pd
import pytest

from tests.conftest import DEMO_SURVEY
from tests.session_helpers import make_session


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    return make_session(tmp_path_factory.mktemp("day"))


SIM = ["simulate", "--survey", DEMO_SURVEY, "--mass", "88", "--cda", "0.22", "--mu", "0.0085",
       "--v0", "3.4", "--air-density", "1.079"]  # fmt: skip


def _commands(session, out: str, option: str = "--csv") -> list[list]:
    return [
        ["export", session, "--csv", out],
        ["replay", session, option, out],
        ["compare", session, "--csv", out],
        ["survey", DEMO_SURVEY, "--csv", out],
        [*SIM, "--csv", out],
    ]


def _one_line(r, *expect: str) -> None:
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    for e in expect:
        assert e in lines[0], lines[0]


@pytest.mark.parametrize("case", ["missing_folder", "folder", "unwritable", "parent_is_file"])
def test_every_output_path_is_checked_first(run_station, session, tmp_path, case):
    if case == "missing_folder":
        out, expect = str(tmp_path / "nope" / "x.csv"), "does not exist"
    elif case == "folder":
        out, expect = str(tmp_path), "is a folder"
    elif case == "unwritable":
        if os.geteuid() == 0:  # root writes anywhere but a read-only file system
            out = "/sys/x.csv"
        else:
            ro = tmp_path / "ro"
            ro.mkdir(mode=0o500)
            out = str(ro / "x.csv")
        expect = "not writable"
    else:
        (tmp_path / "f").write_text("")
        out, expect = str(tmp_path / "f" / "x.csv"), "is not a folder"
    cmds = _commands(session, out) + [["replay", session, "--events", out]]
    for cmd in cmds:
        r = run_station(*cmd)
        _one_line(r, out, expect)
        assert "descent" not in r.stdout  # refused before the day was replayed


def test_a_special_file_is_refused(run_station, session, tmp_path):
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    _one_line(run_station("export", session, "--csv", fifo), "not a regular file")


def test_dash_is_standard_output_and_the_report_goes_to_stderr(run_station, session, tmp_path):
    r = run_station("export", session, "--csv", "-")
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "-").exists()
    df = pd.read_csv(io.StringIO(r.stdout), comment="#")
    assert list(df["descent"]) == list(range(1, 9))
    assert "8 descents -> standard output" in r.stderr
    r = run_station(*SIM, "--csv", "-")
    assert r.returncode == 0 and r.stdout.splitlines()[0] == "photocell,time"  # CRLF: csv's own
    assert "minimum normal force" in r.stderr  # the report, out of the way of the data
    r = run_station("export", session, "--times", "-")
    assert r.returncode == 0 and r.stdout.startswith("descent,bib,photocell,channel")
    assert not (Path.cwd() / "-").exists() and "crossing times -> standard output" in r.stderr
    r = run_station("replay", session, "--events", "-")
    assert r.returncode == 0 and r.stdout.splitlines()[0].startswith("line,channel,photocell")
    assert "descent   8" in r.stderr
    _one_line(run_station(*SIM, "--csv", "-", "--json"), "cannot both go to standard output")
    _one_line(run_station("replay", session, "--csv", "-", "--events", "-"), "cannot both")


def test_a_failed_export_leaves_the_previous_file(run_station, session, tmp_path):
    out = tmp_path / "r.csv"
    assert run_station("export", session, "--csv", out).returncode == 0
    before = out.read_text()
    assert run_station("export", tmp_path / "nosession", "--csv", out).returncode == 2
    assert out.read_text() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv"]  # no temporary left over


def test_annotating_a_descent_the_session_does_not_have_is_refused(run_station, tmp_path):
    session = make_session(tmp_path, order="AB")
    before = (session / "annotations.jsonl").read_text()
    r = run_station("annotate", session, "--descents", "2,99", "--ski", "x")
    _one_line(r, "no descent 99", "it has descents 1–2")
    assert (session / "annotations.jsonl").read_text() == before
    assert run_station("annotate", session, "--from", "99", "--ski", "x").returncode == 0


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["fit", "--masss", "88"], "unrecognized arguments: --masss (did you mean --mass?)"),
        (["fit", "--survey", "s", "--times", "t", "--mas", "88"], "--mas (did you mean --mass?)"),
        (["fit", "--survey", "s", "--times", "t", "--mass", "88", "--masss", "8"], "--mass?"),
    ],
)
def test_an_option_must_be_spelt_out(run_station, args, expect):
    _one_line(run_station(*args), expect)


@pytest.mark.parametrize(
    ("args", "expect"),
    [
        (["fit", "--survey", "s", "--times", "t", "--mass", "880"], "'880' kg is out of range"),
        (
            ["fit", "--survey", "s", "--times", "t", "--mass", "88", "--pressure-hpa", "8350"],
            "'8350' hPa is out of range (300 .. 1100)",
        ),
        (
            ["simulate", "--survey", "s", "--mass", "88", "--air-density", "12"],
            "'12' kg/m³ is out of range",
        ),
        (["annotate", "s", "--descents", "1", "--mass", "880"], "--mass: '880' kg"),
        (["annotate", "s", "--descents", "1", "--pressure-hpa", "8350"], "'8350' hPa"),
    ],
)
def test_a_typed_number_out_of_its_plausible_range_is_refused(run_station, args, expect):
    """The same ranges as the station config and the UI form: a typo is not a measurement."""
    _one_line(run_station(*args), expect)


def test_a_negative_number_with_a_decimal_comma_is_a_value(run_station, tmp_path):
    """``--temperature-c -4,5`` (a cold morning, a German laptop) is -4.5 °C, not an option."""
    session = make_session(tmp_path, order="AB")
    r = run_station("annotate", session, "--descents", "1", "--air-temperature-c", "-4,5")
    assert r.returncode == 0, r.stderr
    assert '"air_temperature_c": -4.5' in (session / "annotations.jsonl").read_text()
    r = run_station("annotate", session, "--descents", "1", "--snow-temperature-c", "-,5")
    assert r.returncode == 0, r.stderr


def test_every_option_has_help():
    """Every option of every command says what it is (and its unit, where it has one)."""
    import argparse

    from station.cli.main import build_parser

    top = build_parser()
    sub = next(a for a in top._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, parser in sub.choices.items():
        assert not parser.allow_abbrev, name
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction):
                continue
            if not action.help:
                missing.append(f"{name} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, missing


def test_sessions_lists_date_descents_items_and_status(run_station, session, tmp_path):
    other = make_session(tmp_path, order="AAB", mus={"A": 0.009, "B": 0.01}, annotate=False)
    (tmp_path / "not-a-session").mkdir()
    folder = session.parent
    os.symlink(other, folder / "zz-second")
    r = run_station("sessions", folder, "--json")
    assert r.returncode == 0, r.stderr
    rows = json.loads(r.stdout)
    assert [os.path.basename(x["path"]) for x in rows] == ["session", "zz-second"]
    first = rows[0]
    assert first["started"].startswith("2026-02-02 09:59")
    assert (first["descents"], first["fitted"], first["invalid"]) == (8, 8, 0)
    assert first["items"] == ["pair A / blue", "pair B / blue"]
    assert first["status"] == "finished"
    assert rows[1]["items"] == ["(no item)"]  # no ski or wax entered
    r = run_station("sessions", folder)
    assert r.returncode == 0 and "pair A / blue; pair B / blue" in r.stdout
    assert "finished" in r.stdout and "2026-02-02" in r.stdout
    # an annotation after recording changes the list as a replay would
    r = run_station("annotate", other, "--descents", "3", "--invalid", "fell")
    assert r.returncode == 0
    r = run_station("sessions", other, "--json")
    assert json.loads(r.stdout)[0]["invalid"] == 1
    _one_line(run_station("sessions", tmp_path / "nope"), "no such folder")
    r = run_station("sessions", tmp_path / "not-a-session")
    assert r.returncode == 0 and "no sessions" in r.stdout


def test_reference_item_by_an_unambiguous_beginning(run_station, session):
    r = run_station("compare", session, "--reference", "PAIR b", "--json")
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["reference"] == "pair B / blue"
    _one_line(run_station("compare", session, "--reference", "pair"), "could be", "pair A / blue")
    _one_line(run_station("compare", session, "--reference", "C"), "no item 'C'")


def test_a_decimal_comma_in_a_number_option(run_station):
    point = run_station(*SIM, "--json")
    comma = run_station(*[a.replace("0.0085", "0,0085") for a in map(str, SIM)], "--json")
    assert comma.returncode == 0, comma.stderr
    assert json.loads(comma.stdout) == json.loads(point.stdout)
    _one_line(run_station(*SIM, "--noise-ms", "1,2.5"), "has both a decimal point and a comma")


def test_annotations_that_would_do_nothing_or_contradict_are_refused(run_station, session):
    """Each of these used to say "1 annotation(s) added" while it annotated nothing (a range
    that runs backwards), said both things (invalid and valid) or a direction off the compass."""
    before = (session / "annotations.jsonl").read_bytes()
    _one_line(run_station("annotate", session, "--descents", "5-3", "--ski", "X"), "backwards")
    _one_line(run_station("annotate", session, "--descents", "2", "--invalid", "x", "--valid"),
              "contradict")  # fmt: skip
    _one_line(run_station("annotate", session, "--descents", "2", "--wind-ms", "2",
                          "--wind-from-deg", "400"), "0 to 360")  # fmt: skip
    assert (session / "annotations.jsonl").read_bytes() == before


def test_station_without_a_command_lists_the_commands(run_station):
    r = run_station()
    _one_line(r, "give a command: survey, simulate, fit")
    assert "demo" in r.stderr and "sessions" in r.stderr


def test_the_summary_counts_in_words_people_use():
    from station.report.text import count

    assert [count(n, "descent") for n in (0, 1, 2)] == ["0 descents", "1 descent", "2 descents"]
