"""One answer everywhere: ``station compare`` (text and ``--json``) and ``station report`` say
"decided" of a pair through the one sequential rule (station/model/sequential.py), and a pair
whose difference the run order cannot tell from the drift, or a joint fit flagged poor, is not
decided anywhere. Sessions as the new-user tryout had them: a demo day with an item skied once,
last; all of one item before the other; residuals beyond the timer's stated precision."""

from __future__ import annotations

import json
import re

import pytest

from tests.session_helpers import make_session

PAIR = "pair A / blue vs pair B / blue: "


def _answers(run_station, session, out) -> tuple[str, dict, str]:
    """What compare's text, compare's JSON and the report's verdict say of A vs B."""
    r = run_station("compare", str(session))
    assert r.returncode == 0, r.stderr
    text = next(line.strip() for line in r.stdout.splitlines() if PAIR in line)
    r = run_station("compare", str(session), "--json")
    assert r.returncode == 0, r.stderr
    out_json = json.loads(r.stdout)
    pair = next(c for c in out_json["comparisons"] if c["b"] == "pair B / blue")
    r = run_station("report", str(session), "--out", str(out))
    assert r.returncode == 0, r.stderr
    page = (out / "session.html").read_text(encoding="utf-8")
    verdict = re.search(r"<section id=\"verdict\">(.*?)</section>", page, flags=re.S).group(1)
    heads = re.findall(r"<li class='(\w+)'>(.*?)</li>", verdict, flags=re.S)
    kind, words = next((k, re.sub(r"<[^>]+>", "", h)) for k, h in heads if "pair B" in h)
    return text, pair, f"{kind}: {words}"


@pytest.fixture(scope="module")
def single_last(tmp_path_factory):
    """A, B skied ABBA, then C once, last (as a short demo session ends)."""
    return make_session(
        tmp_path_factory.mktemp("single"),
        order="ABBAABBAC",
        mus={"A": 0.0085, "B": 0.0095, "C": 0.0090},
    )


def test_an_item_skied_once_last_leaves_the_interleaved_pair_decided(
    run_station, single_last, tmp_path
):
    """The tryout: compare said "decided" and the report "not separable" on one day. C's one
    descent tells nothing about the drift, but A and B interleave: the drift is separable from
    A vs B, the pair is decided, and all three outputs say so."""
    text, pair, report = _answers(run_station, single_last, tmp_path / "o")
    assert text.startswith(PAIR + "decided: pair A / blue faster"), text
    assert pair["decision"]["state"] == "decided" and pair["drift_separable"]
    assert pair["caveat"] == "" and pair["decision"]["reason"] == ""
    assert report.startswith("decided: pair A / blue glides better"), report
    r = run_station("compare", str(single_last))
    assert "NOT SEPARABLE" not in r.stdout and "cannot separate" not in r.stderr
    # C's warning is worded for one item
    assert "pair C / blue: one descent, so no comparison is possible for it" in r.stderr
    assert "one descent each" not in r.stderr


def test_a_pair_the_drift_cannot_be_told_from_is_not_decided_anywhere(run_station, tmp_path):
    """All of A before all of B: Δμ and the drift explain the times alike; the interval may
    exclude 0, yet nothing says "decided"."""
    session = make_session(tmp_path, order="AAAABBBB")
    text, pair, report = _answers(run_station, session, tmp_path / "o")
    why = "the drift is not separable from pair A / blue vs pair B / blue"
    assert text.startswith(PAIR + "not yet: " + why), text
    d = pair["decision"]
    assert d["state"] == "undecided" and d["faster"] is None and why in d["reason"]
    assert not pair["drift_separable"]
    assert report.startswith("open: ") and "not decided: " + why in report, report
    r = run_station("compare", str(session))
    assert "NOT SEPARABLE FROM ITEM" in r.stdout
    assert "cannot separate drift from item for pair A / blue and pair B / blue" in r.stderr


def test_a_poor_joint_fit_is_not_decided_anywhere(run_station, tmp_path):
    """Residuals of 0.2 ms against a timer said to be 0.1 ms: POOR FIT, and no decision."""
    session = make_session(tmp_path, noise_ms=0.2, config_extra="timer: {precision_ms: 0.1}\n")
    text, pair, report = _answers(run_station, session, tmp_path / "o")
    assert text.startswith(PAIR + "not yet: the joint fit is a poor fit"), text
    assert pair["decision"]["state"] == "undecided"
    assert "poor fit" in pair["decision"]["reason"]
    assert report.startswith("open: ") and "not decided: the joint fit is a poor fit" in report


def test_decide_obeys_a_caveat_whatever_the_interval():
    from station.model.sequential import decide
    from station.report.comparison_text import decision_words as describe

    run = "ABBAABBA"
    assert decide("A", "B", -0.001, 1e-5, 50.0, run).state == "decided"
    d = decide("A", "B", -0.001, 1e-5, 50.0, run, margin=0.1, caveat="the reason")
    assert d.state == "undecided" and d.faster is None and d.reason == "the reason"
    assert describe(d) == "not yet: the reason"


@pytest.mark.parametrize(
    ("p", "words"),
    [(0.9999, "p > 0.99"), (0.996, "p > 0.99"), (0.36, "p = 0.36"), (1e-9, "p < 0.001")],
)
def test_chi2_p_never_reads_as_one(p, words):
    from station.report.comparison_text import chi2_p_words

    assert chi2_p_words(p) == words


def test_every_status_has_a_short_code_in_the_narrow_table_and_the_readme():
    """A poor-fit descent showed ``?`` in the 80-column table's ``st``: every status the
    results can hold has its short code, and the README's list names each."""
    import pathlib

    from station.session.records import ResultStatus
    from station.ui.app import SHORT_STATUS

    assert {s.value for s in ResultStatus} <= set(SHORT_STATUS)
    assert SHORT_STATUS["poor-fit"] == "poor"
    readme = (pathlib.Path(__file__).parents[1] / "README.md").read_text(encoding="utf-8")
    listed = re.search(r"`st` is the status, short:(.*?)From 130 columns", readme, flags=re.S)
    words = set(re.findall(r"[A-Za-z]+", " ".join(re.findall(r"`([^`]*)`", listed.group(1)))))
    assert set(SHORT_STATUS.values()) <= words
