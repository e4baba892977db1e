"""The results CSV as a user opens it: pandas with comment="#", or a spreadsheet."""

from __future__ import annotations

import pandas as pd

from station.session.results import COLUMNS, read_results, write_results


def test_results_csv_round_trip_and_spreadsheet_safety(tmp_path):
    rows = [
        {c: None for c in COLUMNS}
        | {"descent": 1, "start_time": "2026-02-02T10:41:07.234500", "photocells_used": 9,
           "mu": 0.008452428372456, "mu_lo": 0.0083, "mu_hi": 0.0086, "status": "ok",
           "notes": "pair #3, hard snow", "wax": "=HYPERLINK(\"x\")", "ski": "+A", "skier": "@me",
           "missing": "", "mass_kg": 88.0},
        {c: None for c in COLUMNS}
        | {"descent": 2, "start_time": "2026-02-02T10:45:00", "photocells_used": 1,
           "status": "aborted", "flags": "-lone start impulse", "mass_kg": 88.0},
    ]  # fmt: skip
    path = tmp_path / "results.csv"
    write_results(rows, str(path), {"survey": "Demo run", "config": "station.yaml"})
    text = path.read_text()
    assert text.startswith("# station ") and "# survey: Demo run\n" in text
    body = [ln for ln in text.splitlines() if not ln.startswith("#")]
    assert body[1].startswith('1,"2026-02-02T10:41:07.234500",9,')  # numbers are not quoted
    assert "0.008452428372456" in body[1]  # at full precision
    df = pd.read_csv(path, comment="#")
    assert list(df.columns) == COLUMNS
    assert df.loc[0, "mu"] == 0.008452428372456
    assert df.loc[0, "notes"] == "pair #3, hard snow"
    assert df.loc[0, "wax"] == '\'=HYPERLINK("x")'
    assert df.loc[0, "ski"] == "'+A" and df.loc[0, "skier"] == "'@me"
    assert df.loc[1, "flags"] == "'-lone start impulse"
    assert pd.isna(df.loc[1, "mu"]) and df["mu"].dtype == float


def test_header_lines_have_no_commas_and_name_the_units(tmp_path):
    from station.session.results import UNITS

    rows = [{c: None for c in COLUMNS} | {"descent": 1, "start_time": "2026-02-02T10:41:07+01:00",
                                           "photocells_used": 9, "mass_kg": 88.0}]  # fmt: skip
    path = tmp_path / "results.csv"
    header = {"survey": "Run, lower part (run.yaml, sha256 0e94)", "notes": "a\nb, c"}
    write_results(rows, str(path), header)
    heads = [ln for ln in path.read_text().splitlines() if ln.startswith("#")]
    assert heads[1] == "# survey: Run | lower part (run.yaml | sha256 0e94)"
    assert heads[2] == "# notes: a b | c"
    assert all("," not in ln and ";" not in ln for ln in heads), heads
    units = dict(part.split(" ", 1) for part in heads[-1].removeprefix("# units: ").split(" | "))
    numeric = [c for c in COLUMNS if c not in ("missing", "status", "descent_status", "flags",
               "model", "skier", "ski", "wax", "notes", "invalid_reason")]  # fmt: skip
    assert set(numeric) <= set(units) and units["cda"] == "m2" and units["v0"] == "m/s"
    assert set(UNITS) <= set(COLUMNS)
    df = pd.read_csv(path, comment="#")
    assert list(df.columns) == COLUMNS and df.loc[0, "start_time"] == "2026-02-02T10:41:07+01:00"


def test_start_time_carries_the_local_offset_of_its_date(monkeypatch):
    """The timer sends local time of day: the offset is the host's for that date (winter and
    summer time differ), so the instant is known wherever the file is read."""
    import datetime as dt
    import time
    from types import SimpleNamespace

    from station.session.analysis import start_time

    monkeypatch.setenv("TZ", "Europe/Zurich")
    time.tzset()
    try:
        d = SimpleNamespace(start_us=(10 * 3600 + 41 * 60 + 7) * 10**6 + 234500, day=None)
        winter = start_time(d, None, dt.date(2026, 2, 2))
        summer = start_time(d, None, dt.date(2026, 7, 2))
        host = start_time(d, dt.datetime(2026, 2, 2, 10, 41, 9).timestamp(), None)
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    assert winter == "2026-02-02T10:41:07.234500+01:00"
    assert summer == "2026-07-02T10:41:07.234500+02:00"
    assert host == winter
    assert dt.datetime.fromisoformat(winter).utcoffset() == dt.timedelta(hours=1)


def test_read_results_without_pandas_gives_what_was_written(tmp_path):
    rows = [
        {"descent": 1, "photocells_used": 9, "mu": 0.008452428372456, "status": "ok",
         "notes": "pair 3\n# not a header", "ski": "=A", "start_time": "10:41:07"},
        {"descent": 2, "photocells_used": 1.0, "cda": float("nan"), "status": "aborted"},
    ]  # fmt: skip
    path = tmp_path / "results.csv"
    write_results(rows, str(path), {"survey": "Demo run"})
    back = read_results(str(path))
    assert [list(r) for r in back] == [COLUMNS, COLUMNS]
    assert back[0]["descent"] == 1 and isinstance(back[0]["descent"], int)
    assert back[0]["mu"] == 0.008452428372456 and back[0]["cda"] is None
    assert back[0]["notes"] == "pair 3\n# not a header" and back[0]["ski"] == "'=A"
    assert back[1]["photocells_used"] == 1 and back[1]["status"] == "aborted"
    assert back[1]["cda"] is None and back[1]["start_time"] is None
    assert pd.read_csv(path, comment="#")["mu"].iloc[0] == back[0]["mu"]


HOSTILE = [
    "=1+2",
    "\t=cmd|' /C calc'!A0",
    "\r=1+2",
    "\n=1+2",
    "   @SUM(A1)",
    " \t\r\n-2+3",
    "\u00a0+1",
    "\uff1d1+2",
    "\t",
    'pair "3", hard; snow\r\n# not a comment',
]


def _row(n: int, **text) -> dict:
    return {c: None for c in COLUMNS} | {"descent": n, "status": "ok"} | text


def _nl(text: str) -> str:
    return text.replace("\r\n", "\n")


def _formula_like(cell: str) -> bool:
    """What a spreadsheet would run: a formula character after any leading whitespace."""
    return cell.lstrip(" \t\r\n\u00a0")[:1] in ("=", "+", "-", "@", "\uff1d")


def test_no_cell_a_spreadsheet_would_run_whatever_its_leading_whitespace(tmp_path):
    import csv

    rows = [_row(i + 1, notes=h, wax=h, ski=h, skier=h, flags=h) for i, h in enumerate(HOSTILE)]
    path = tmp_path / "results.csv"
    write_results(rows, str(path), {"survey": "Demo"})
    with open(path, newline="", encoding="utf-8") as fh:
        cells = [c for r in csv.reader(ln for ln in fh if not ln.startswith("#")) for c in r]
    assert not [c for c in cells if _formula_like(c)]
    df = pd.read_csv(path, comment="#")
    assert len(df) == len(HOSTILE)
    # the text is kept, only prefixed: nothing the engineer typed is lost
    for got, typed in zip(df["notes"], HOSTILE, strict=True):
        assert _nl(got) in (_nl(typed), _nl("'" + typed))


def test_hostile_header_values_never_break_read_csv(tmp_path):
    header = {
        "survey": 'Run "A",\r\nsecond line\r=cmd;x',
        "notes": "a,b;c\tç\u2028d\x00e",
        "we\nird": "#, \"'",
    }
    path = tmp_path / "results.csv"
    write_results([_row(1, notes="x")], str(path), header)
    lines = path.read_text(encoding="utf-8").split("\n")
    comments = [ln for ln in lines if ln.startswith("#")]
    assert len(comments) == 1 + len(header) + 1  # the title, the header, the units
    assert not any(ch in ln for ln in comments for ch in ",;\r\t\x00\u2028")
    df = pd.read_csv(path, comment="#")
    assert list(df.columns) == COLUMNS and len(df) == 1 and df.loc[0, "notes"] == "x"


def test_results_are_written_with_the_users_umask(tmp_path):
    import os

    old = os.umask(0o027)
    try:
        path = tmp_path / "results.csv"
        write_results([_row(1)], str(path), {})
        assert os.stat(path).st_mode & 0o777 == 0o640
        os.umask(0o002)
        write_results([_row(1)], str(path), {})
        assert os.stat(path).st_mode & 0o777 == 0o664
    finally:
        os.umask(old)


def test_the_air_header_says_the_density_once(tmp_path):
    from station.session.config import load_config
    from station.session.folder import results_header
    from tests.timing_helpers import write_config

    given = results_header(load_config(str(write_config(tmp_path, "loop://"))), "Demo run")
    assert given["air"] == "density 1.0790 kg/m3"
    cfg = (
        write_config(tmp_path, "loop://")
        .read_text()
        .replace(
            "air: {density: 1.079}", "air: {pressure_hpa: 835, temperature_c: -4, humidity_pct: 70}"
        )
    )
    (tmp_path / "station.yaml").write_text(cfg)
    air = results_header(load_config(str(tmp_path / "station.yaml")), "Demo run")["air"]
    assert air.startswith("pressure_hpa 835 | temperature_c -4 | humidity_pct 70 | density 1.")
    assert air.count("density") == 1


def test_the_trackside_shows_the_start_without_its_utc_offset():
    from station.report.text import local_time

    assert local_time("2026-02-02T10:41:07.234500+01:00") == "2026-02-02 10:41:07.23"
    assert local_time("2026-02-02T10:03:00-05:00") == "2026-02-02 10:03:00"
    assert local_time("10:41:07.2345") == "10:41:07.2345"  # a capture without a date


def test_a_descent_marked_invalid_is_not_ok_in_the_csv(tmp_path, run_station):
    """It kept status "ok": whoever filtered the CSV on the status kept the descent."""
    from tests.session_helpers import make_session

    session = make_session(tmp_path, order="AB")
    r = run_station("annotate", session, "--descents", "2", "--invalid", "fell at PC4")
    assert r.returncode == 0, r.stderr
    rows = read_results(str(session / "results.csv"))
    assert [(x["status"], x["invalid_reason"]) for x in rows] == [
        ("ok", None), ("invalid", "fell at PC4")
    ]  # fmt: skip
    assert rows[1]["mu"] is not None  # its fit is still there
    r = run_station("annotate", session, "--descents", "2", "--valid")
    assert r.returncode == 0, r.stderr
    assert [x["status"] for x in read_results(str(session / "results.csv"))] == ["ok", "ok"]
