"""Station config: every wrong key or value is one clear line with file, line and field."""

from __future__ import annotations

import pytest

from tests.timing_helpers import write_config


@pytest.mark.parametrize(
    ("change", "expect"),
    [
        (
            ("protocol: alge", "protocol: omega"),
            ":1: field serial.protocol: unknown protocol 'omega'",
        ),
        (
            ("baudrate: 9600", "baudrate: fast"),
            ":1: field serial.baudrate: expected a whole number",
        ),
        (
            ("skier: {mass_kg: 88", "skier: {mass_kg: -88"),
            ":4: field skier.mass_kg: must be greater",
        ),
        (("air: {density: 1.079}", "air: {densty: 1.079}"), ":5: field air.densty: unknown key"),
        (
            ("name: Test skier}", "name: Test skier}\nfitt: {model: velocity}"),
            ":5: field fitt: unknown key",
        ),
        (("'C8': PC9", "'C8': PC42"), "field photocells.C8: photocell 'PC42' is not in the survey"),
        (("survey: ", "survey: nowhere.yaml #"), ":2: field survey: survey file 'nowhere.yaml"),
    ],
)
def test_config_errors(tmp_path, run_station, change, expect):
    cfg = write_config(tmp_path, "loop://")
    text = cfg.read_text()
    assert change[0] in text
    cfg.write_text(text.replace(change[0], change[1], 1))
    r = run_station("replay", cfg, "--config", cfg)  # any command that loads the config
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in r.stderr
    assert expect in lines[0], lines[0]


def test_a_plain_capture_needs_a_config(tmp_path, run_station):
    cap = tmp_path / "cap.txt"
    cap.write_bytes(b" 0001 C0  10:00:00.0000 00\r")
    r = run_station("replay", cap)
    assert r.returncode == 2 and "needs --config" in r.stderr
    r = run_station("export", cap, "--csv", tmp_path / "x.csv")
    assert r.returncode == 2 and "not a session directory" in r.stderr
