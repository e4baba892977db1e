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
            ":4: field skier.mass_kg: must lie between 20 and 200 kg, got -88.0",
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


def _load(tmp_path, old: str, new: str):
    from station.session.config import load_config

    cfg = write_config(tmp_path, "loop://", extra="descent: {debounce_s: 0.3}\n")
    text = cfg.read_text()
    assert old in text
    cfg.write_text(text.replace(old, new, 1))
    return load_config(str(cfg))


BAD_NUMBERS = [
    ("mass_kg: 88", "mass_kg: .nan", ":4: field skier.mass_kg: must be a finite number, got nan"),
    ("mass_kg: 88", "mass_kg: .inf", "field skier.mass_kg: must be a finite number, got inf"),
    ("mass_kg: 88", "mass_kg: 1.0e+308", "skier.mass_kg: must lie between 20 and 200 kg"),
    ("mass_kg: 88", "mass_kg: 1e308", "skier.mass_kg: must lie between 20 and 200 kg"),
    ("mass_kg: 88", "mass_kg: 885", "skier.mass_kg: must lie between 20 and 200 kg, got 885.0"),
    ("mass_kg: 88", "mass_kg: " + "9" * 400, "skier.mass_kg: the number 999"),
    ("mass_kg: 88", "mass_kg: '1,234.5'", "skier.mass_kg: expected a number: '1,234.5' has both"),
    (
        "mass_kg: 88",
        "mass_kg: 72,5",
        "field skier.5: unknown key (known keys: mass_kg, name); a decimal",
    ),
    ("density: 1.079", "density: -.inf", "air.density: must be a finite number"),
    ("density: 1.079", "density: 10", "air.density: must lie between 0.3 and 2 kg/m³"),
    ("{density: 1.079}", "{pressure_hpa: .nan, temperature_c: 0}", "air.pressure_hpa: must be a"),
    ("{density: 1.079}", "{pressure_hpa: 101325, temperature_c: 0}", "between 300 and 1100 hPa"),
    ("{density: 1.079}", "{pressure_hpa: 835, temperature_c: 300}", "air.temperature_c: must lie"),
    ("{density: 1.079}", "{pressure_hpa: 835, temperature_c: 0, humidity_pct: 101}", "humidity"),
    ("debounce_s: 0.3", "debounce_s: .nan", ":6: field descent.debounce_s: must be a finite"),
    ("debounce_s: 0.3", "debounce_s: -1", "descent.debounce_s: must lie between 0 and 5 s"),
    ("debounce_s: 0.3", "timeout_s: .inf", "descent.timeout_s: must be a finite number"),
    ("debounce_s: 0.3", "timeout_s: 0", "descent.timeout_s: must lie between 1 and 3600 s"),
    ("debounce_s: 0.3", "min_speed_ms: .nan", "descent.min_speed_ms: must be a finite number"),
    ("debounce_s: 0.3", "min_speed_ms: 1e-9", "descent.min_speed_ms: must lie between 0.1"),
    ("baudrate: 9600", "baudrate: 10000000000000000", "serial.baudrate: must lie between 50"),
    ("'C1': PC2", "'C1': PC1", ":3: field photocells.C1: photocell PC1 is already on channel C0"),
    ("port: loop://", "port: ''", ":1: field serial.port: not a port name: ''"),
]


@pytest.mark.parametrize(("old", "new", "expect"), BAD_NUMBERS)
def test_every_number_is_finite_and_in_a_physical_range(tmp_path, old, new, expect):
    from station.errors import InputError

    with pytest.raises(InputError) as err:
        _load(tmp_path, old, new)
    assert expect in str(err.value)
    assert "\n" not in str(err.value)


def test_a_decimal_comma_is_a_decimal_mark(tmp_path):
    cfg = _load(tmp_path, "mass_kg: 88", "mass_kg: '72,5'")
    assert cfg.mass_kg == 72.5
    cfg = _load(tmp_path, "density: 1.079", "density: '1,079'")
    assert cfg.air_density == 1.079


@pytest.mark.parametrize(
    ("text", "expect"),
    [
        ("a: " + "[" * 20000 + "]" * 20000, ":1: not valid YAML: nested deeper than 64 levels"),
        ("a: &a [*a]", "an alias refers to itself"),
        ("? [a]\n: 1", "a key must be a plain value"),
        ("a: " + "9" * 5000, "a number with thousands of digits"),
        ("a: 1\n\xff: 2", "not a UTF-8 text station config (byte 0xff)"),
    ],
)
def test_hostile_yaml_is_one_line(tmp_path, text, expect):
    from station.errors import InputError
    from station.session.config import load_config

    path = tmp_path / "c.yaml"
    path.write_bytes(text.encode("latin-1"))
    with pytest.raises(InputError, match=expect.replace("(", r"\(").replace(")", r"\)")):
        load_config(str(path))


def test_a_billion_laughs_is_refused_at_once(tmp_path):
    import time

    from station.errors import InputError
    from station.session.config import load_config

    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, name in zip("abcdefgh", "bcdefghi", strict=True):
        lines.append(f"{name}: &{name} [" + ",".join([f"*{prev}"] * 9) + "]")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    t0 = time.monotonic()
    with pytest.raises(InputError, match="expands to more than"):
        load_config(str(path))
    assert time.monotonic() - t0 < 2


@pytest.mark.parametrize("special", ["/dev/zero", "fifo", "folder", "unreadable", "missing"])
def test_special_and_unreadable_files_are_one_line(tmp_path, special):
    import os

    from station.errors import InputError
    from station.session.config import load_config

    if special == "fifo":
        path = tmp_path / "fifo.yaml"
        os.mkfifo(path)
        expect = "is a pipe (FIFO), not a station config"
    elif special == "folder":
        path = tmp_path
        expect = "is a folder, not a station config"
    elif special == "unreadable":
        if os.geteuid() == 0:
            pytest.skip("root reads everything")
        path = tmp_path / "secret.yaml"
        path.write_text("a: 1\n")
        path.chmod(0)
        expect = "permission denied"
    elif special == "missing":
        path = tmp_path / "nowhere.yaml"
        expect = "cannot read station config: no such file"
    else:
        path = special
        expect = "is a character device, not a station config"
    with pytest.raises(InputError, match=expect.replace("(", r"\(").replace(")", r"\)")):
        load_config(str(path))


def test_a_survey_that_is_a_special_file_is_refused_at_the_survey_line(tmp_path):
    from station.errors import InputError

    with pytest.raises(InputError) as err:
        _load(tmp_path, "survey: ", "survey: /dev/zero #")
    assert ":2: field survey: survey file '/dev/zero': is a character device" in str(err.value)


def test_a_config_that_does_not_fit_its_survey_makes_no_session(tmp_path, run_station):
    """Found by a new-user trial: the error named the session's copy of the config, and the
    half-made folder made the corrected second try fail as "not empty"."""
    cfg = write_config(tmp_path, "loop://")
    good = cfg.read_text()
    cfg.write_text(good.replace("'C8': PC9", "'C8': PC42", 1))
    session = tmp_path / "day1"
    r = run_station("record", "--config", cfg, "--session-dir", session, "--duration", "0.2")
    assert r.returncode == 2, r.stdout + r.stderr
    assert str(cfg) in r.stderr and "photocell 'PC42' is not in the survey" in r.stderr
    assert not session.exists()
    cfg.write_text(good)
    r = run_station("record", "--config", cfg, "--session-dir", session, "--duration", "0.2")
    assert r.returncode == 0, r.stderr
    assert (session / "raw.jsonl").exists()
