"""One CSV policy for every file the station writes (issue 18, station.csvfiles): a text cell
a spreadsheet would run is shown as text, a number stays a number, and a header line holds
whatever a name contains on one line."""

from __future__ import annotations

import csv
import io

from station import csvfiles
from tests.session_helpers import T0, make_session


def test_cells_are_formula_safe_and_numbers_stay_numbers():
    fh = io.StringIO()
    w = csvfiles.writer(fh)
    w.writerow(["=1+2", " \t@SUM(A1)", "-0.125", "+3", "1e-05", "-2+3", "\uff1dX", 7, -1.5, None])
    row = next(csv.reader(io.StringIO(fh.getvalue())))
    assert row == ["'=1+2", "' \t@SUM(A1)", "-0.125", "+3", "1e-05", "'-2+3", "'\uff1dX", "7",
                   "-1.5", ""]  # fmt: skip
    assert csvfiles.header_line("survey", "a, b; c\r\n# x") == "# survey: a | b | c # x"


def test_compare_csv_writes_item_names_safely(tmp_path, run_station):
    from station.session import folder as session_folder
    from station.session.records import Metadata, MetadataAnnotation

    session = make_session(tmp_path, order="ABBAABBA", annotate=False)
    names = {"A": '=HYPERLINK("http://x")', "B": "pair B\n# live, row; here"}
    for item, name in names.items():
        numbers = tuple(k + 1 for k, it in enumerate("ABBAABBA") if it == item)
        session_folder.append_annotation(
            str(session), MetadataAnnotation(Metadata(ski=name), descents=numbers, t=T0)
        )
    out = tmp_path / "cmp.csv"
    r = run_station("compare", session, "--csv", out, "--reference", "pair")
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    head, columns, *rows = _records(text)
    assert head[0].startswith("# station") and len(head) == 1 and "," not in head[0]
    assert "reference pair B # live | row | here" in head[0]
    assert columns[:2] == ["rank", "item"] and len(rows) == 2
    assert {row[1] for row in rows} == {"'" + names["A"], "pair B\n# live, row; here"}
    import pandas as pd

    assert len(pd.read_csv(out, comment="#")) == 2


def _records(text: str) -> list:
    """The header line (as a one-element list), then the CSV records after it."""
    first, rest = text.split("\n", 1)
    return [[first], *csv.reader(io.StringIO(rest))]
