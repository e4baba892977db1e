"""The snow as testers record it, and grind and base beside ski and wax: one table
(records.METADATA_FIELDS) gives `station annotate` its options, the UI its form fields and the
season store its columns; results.csv keeps its columns (its bytes do not change)."""

from __future__ import annotations

import datetime as dt

from station.session import folder as sessions
from station.session.records import HARDNESS, METADATA_FIELDS, SNOW_TYPES, WETNESS
from station.session.results import COLUMNS
from tests.season_helpers import make_day


def test_the_classes_are_the_international_classification():
    assert SNOW_TYPES == ("PP", "MM", "DF", "RG", "FC", "DH", "SH", "MF", "IF")
    assert WETNESS == ("dry", "moist", "wet", "very wet", "soaked")
    assert HARDNESS == ("F", "4F", "1F", "P", "K", "I")
    keys = [f.key for f in METADATA_FIELDS]
    for k in ("grind", "base", "snow_type", "grain_size_mm", "wetness", "hardness"):
        assert k in keys and k not in COLUMNS  # results.csv keeps its columns


def test_annotate_takes_the_snow_as_typed(run_station, tmp_path):
    day = make_day(tmp_path, "d", dt.date(2026, 1, 5), "ABBA", {"A": 0.01, "B": 0.011})
    before = (day / "annotations.jsonl").read_text()
    r = run_station("annotate", day, "--from", "1", "--snow-type", "mf", "--wetness", "V",
                    "--hardness", "4f", "--grain-size-mm", "1,5", "--grind", "linear 0.5",
                    "--base", "cold")  # fmt: skip
    assert r.returncode == 0, r.stderr
    last = sessions.read_annotations(str(day))[-1].values
    assert (last.snow_type, last.wetness, last.hardness) == ("MF", "very wet", "4F")
    assert (last.grain_size_mm, last.grind, last.base) == (1.5, "linear 0.5", "cold")
    r = run_station("annotate", day, "--from", "1", "--snow-type", "slush")
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0
    assert "snow_type" in r.stderr and "PP, MM" in r.stderr
    assert len((day / "annotations.jsonl").read_text()) > len(before)


def test_the_results_csv_header_is_unchanged_by_the_snow(run_station, tmp_path):
    day = make_day(tmp_path, "d", dt.date(2026, 1, 5), "ABBA", {"A": 0.01, "B": 0.011})
    out1 = tmp_path / "a.csv"
    assert run_station("export", day, "--csv", out1).returncode == 0
    run_station("annotate", day, "--from", "1", "--snow-type", "PP", "--hardness", "F")
    out2 = tmp_path / "b.csv"
    assert run_station("export", day, "--csv", out2).returncode == 0
    assert out1.read_bytes() == out2.read_bytes()
