"""First-day traps: options and paths a tester may type wrong get one line naming what is
wrong and exit status 2, not a silent answer to another question."""

from __future__ import annotations

import json

import pytest

from tests.timing_helpers import write_config


@pytest.fixture(scope="module")
def day(tmp_path_factory):
    """Eight descents, ABBAABBA."""
    from tests.session_helpers import make_session

    return make_session(tmp_path_factory.mktemp("day"), order="ABBAABBA")


@pytest.mark.parametrize(("value", "words"), [("0", "at least 1 descent"),
                                             ("-1", "at least 1 descent"),
                                             ("2,5", "must be a whole number")])  # fmt: skip
def test_record_max_descents_is_a_whole_number_of_at_least_one(run_station, tmp_path, value,
                                                                words):  # fmt: skip
    cfg = write_config(tmp_path, "/dev/null")
    r = run_station("record", "--config", cfg, "--session-dir", tmp_path / "s",
                    "--max-descents", value)  # fmt: skip
    assert r.returncode == 2 and words in r.stderr
    assert not (tmp_path / "s").exists()  # no empty session made


def test_compare_upto_a_descent_the_day_does_not_have_is_refused(run_station, day):
    r = run_station("compare", day, "--upto", "99")
    assert r.returncode == 2, r.stdout
    assert "--upto" in r.stderr and "no descent 99 in this session (it has descents 1–8)" in (
        r.stderr
    )
    assert r.stdout == ""


def test_compare_of_a_folder_that_does_not_exist_says_so(run_station, tmp_path):
    r = run_station("compare", tmp_path / "nosuch")
    assert r.returncode == 2 and "no such session folder" in r.stderr
    assert "not a session directory" not in r.stderr


def test_compare_with_the_velocity_model_converges_and_decides(run_station, day):
    """μ + μ1·v per item: μ1 is a slope of either sign (it was held at ≥ 0 like μ, so the
    joint fit never reached its minimum when the estimate was negative)."""
    r = run_station("compare", day, "--model", "velocity", "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["status"] == "ok", out["message"]
    assert all("mu1" in it for it in out["items"])
    assert out["comparisons"][0]["decision"]["reason"] == ""
