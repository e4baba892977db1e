"""``station check CONFIG``: config, survey and photocell mapping checked without a timer, one
line per problem; ``record`` and ``live`` run the same checks before the port."""

from __future__ import annotations

from tests.timing_helpers import write_config

BAD_CHANNELS = {"C0": "PC1", "C1": "PC2", "C2": "PCX", "C3": "PC99"}


def test_every_photocell_problem_is_one_line(tmp_path, run_station):
    cfg = write_config(tmp_path, "/dev/ttyUSB7", channels=BAD_CHANNELS)
    r = run_station("check", cfg)
    assert r.returncode == 2
    lines = r.stdout.splitlines()
    assert lines == [
        f"{cfg}: field photocells.C2: photocell 'PCX' is not in the survey "
        "(PC1, PC2, PC3, PC4, PC5, PC6, PC7, PC8, PC9)",
        f"{cfg}: field photocells.C3: photocell 'PC99' is not in the survey "
        "(PC1, PC2, PC3, PC4, PC5, PC6, PC7, PC8, PC9)",
    ]
    assert r.stderr == f"station check: 2 problems in {cfg}\n"


def test_a_good_config_is_ok_without_its_timer(tmp_path, run_station):
    cfg = write_config(tmp_path, str(tmp_path / "no-timer-here"))
    r = run_station("check", cfg)
    assert r.returncode == 0, r.stdout + r.stderr
    assert r.stdout == (
        f"ok: {cfg}: alge timer on {tmp_path / 'no-timer-here'} (not attached now), 9 channels "
        "to 9 of the 9 photocells of Demo run (simulated survey) (344.2 m, 72.3 m drop), "
        "skier 88 kg\n"
    )
    assert r.stderr == ""


def test_unmapped_photocells_are_a_note_not_a_problem(tmp_path, run_station):
    cfg = write_config(tmp_path, "socket://localhost:9", channels={"C0": "PC1", "C1": "PC9"})
    r = run_station("check", cfg)
    assert r.returncode == 0
    assert r.stdout.startswith(f"ok: {cfg}: alge timer on socket://localhost:9, 2 channels to 2")
    assert r.stderr == (
        f"note: {cfg}: field photocells: no channel for PC2, PC3, PC4, PC5, PC6, PC7, PC8 of "
        "the survey: descents will be timed without them\n"
    )


def test_a_survey_that_cannot_be_read_is_one_line(tmp_path, run_station):
    survey = tmp_path / "survey.yaml"
    survey.write_text("points: [1, 2\n")
    cfg = write_config(tmp_path, "/dev/ttyUSB7")
    lines = [f"survey: {survey}" if x.startswith("survey:") else x
             for x in cfg.read_text().splitlines()]  # fmt: skip
    cfg.write_text("\n".join(lines) + "\n")
    r = run_station("check", cfg)
    assert r.returncode == 2
    assert len(r.stdout.splitlines()) == 1 and r.stdout.startswith(f"{survey}:"), r.stdout


def test_record_and_live_check_the_config_before_the_port(tmp_path, run_station):
    """They said the port was missing and nothing of the photocell the survey lacks: the
    config could not be checked without the timer."""
    cfg = write_config(tmp_path, "/dev/ttyUSB7", channels=BAD_CHANNELS)
    for command in ("record", "live"):
        r = run_station(command, "--config", cfg, "--session-dir", tmp_path / command)
        assert r.returncode == 2
        assert r.stderr == (
            f"station: error: {cfg}: field photocells.C2: photocell 'PCX' is not in the survey "
            f"(PC1, PC2, PC3, PC4, PC5, PC6, PC7, PC8, PC9) (and 1 more: station check {cfg})\n"
        ), command
        assert not (tmp_path / command).exists()
    good = write_config(tmp_path, "/dev/ttyUSB7")
    r = run_station("record", "--config", good, "--session-dir", tmp_path / "s")
    assert r.returncode == 2 and "serial port /dev/ttyUSB7 does not exist" in r.stderr


def test_the_readme_example(run_station, monkeypatch):
    """As the README shows it, from the checkout (the demo timer's pseudo-terminal absent)."""
    import re

    from tests.conftest import ROOT

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    shown = re.search(r"\$ station check surveys/demo_station.yaml\n(.*?)\n```", readme, re.S)
    r = run_station("check", "surveys/demo_station.yaml", cwd=ROOT)
    assert r.returncode == 0
    out = r.stdout
    if "(not attached now)" not in out:  # a demo timer running on this machine
        out = out.replace("/tmp/station-timer,", "/tmp/station-timer (not attached now),")
    assert out == shown.group(1) + "\n"
