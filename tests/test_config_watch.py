"""A config that does not match the timer is said within seconds of the first lines, not
discovered at the end of the day: unmapped channels and lines of another protocol."""

from __future__ import annotations

import re
import subprocess
import time

import pytest

from station.session.records import LineCounts
from station.session.watch import AGAIN_S, ConfigWatch
from station.timing.assembly import ImpulseEvent
from station.timing.wireformats import format_alge
from tests.conftest import station_cmd
from tests.timing_helpers import ALGE_CHANNELS, start_sim, write_config

TAG_CHANNELS = {str(i + 1): f"PC{i + 1}" for i in range(9)}


def event(channel: str, photocell: str | None) -> ImpulseEvent:
    return ImpulseEvent(1, channel, photocell, 36_000_000_000, "", photocell is not None)


def test_impulses_on_unmapped_channels_are_named_with_what_the_config_maps():
    watch = ConfigWatch("microgate", ALGE_CHANNELS)
    counts = LineCounts(lines=2, impulses=2)
    assert watch.note([event("000", None)], counts, [], 0.0) == []  # one may be a stray
    (said,) = watch.note([event("001", None)], counts, [], 0.5)
    assert "channel 000 (1×), 001 (1×)" in said and "maps C0, C1, C2" in said
    assert watch.note([event("000", None)], counts, [], 10.0) == []  # said once a minute
    assert watch.note([], counts, [], 0.5 + AGAIN_S) != []


def test_mapped_channels_and_a_photocell_say_nothing():
    watch = ConfigWatch("alge", ALGE_CHANNELS)
    events = [event("C0", "PC1"), event("C1", "PC2"), event("C5", "PC6")]
    assert watch.note(events, LineCounts(lines=3, impulses=3), [], 0.0) == []


def test_lines_of_another_protocol_are_named_with_the_protocol_they_parse_as():
    alge = [format_alge(f"C{k}", 36_000_000_000 + k * 1_000_000) for k in range(5)]
    watch = ConfigWatch("tag", TAG_CHANNELS)
    assert watch.note([], LineCounts(lines=3, unparsed=3), alge[:3], 0.0) == []
    (said,) = watch.note([], LineCounts(lines=5, unparsed=5), alge[3:], 1.0)
    assert said.startswith("5 lines from the timer, none of them an impulse as tag sends it")
    assert "they parse as alge: set serial: protocol: alge in the config" in said


def test_garbage_among_impulses_is_no_wrong_protocol():
    watch = ConfigWatch("alge", ALGE_CHANNELS)
    assert watch.note([], LineCounts(lines=30, impulses=20, unparsed=10), ["#"] * 10, 0.0) == []


def _record_until_warned(tmp_path, sim_args: list[str], protocol: str, channels: dict) -> float:
    """``station record`` against the simulated timer with a config that does not match it:
    the seconds from its start to the warning on its console (the recording is then ended)."""
    sim, port, _truth = start_sim(tmp_path, "--speed", "10", "--first-after", "1",
                                  "--descents", "1", "--hold", "20", *sim_args)  # fmt: skip
    cfg = write_config(tmp_path, port, protocol, channels)
    t0 = time.monotonic()
    rec = subprocess.Popen(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir", str(tmp_path / "s")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert rec.stdout is not None
        for line in rec.stdout:
            if line.startswith("warning: "):
                return time.monotonic() - t0
        raise AssertionError(f"no warning: {rec.stderr.read() if rec.stderr else ''}")
    finally:
        rec.terminate()
        rec.communicate(timeout=60)
        sim.kill()
        sim.wait(timeout=30)


@pytest.mark.slow  # a simulated timer on a pty, in real time
@pytest.mark.parametrize(
    ("sim_protocol", "protocol", "channels", "words"),
    [
        ("microgate", "microgate", ALGE_CHANNELS, r"channel 000 \(\d+×\)"),
        ("alge", "tag", TAG_CHANNELS, "they parse as alge"),
    ],
)
def test_record_warns_within_seconds_of_a_config_that_does_not_match_the_timer(
    tmp_path, sim_protocol, protocol, channels, words
):
    sim_args = ["--protocol", sim_protocol]
    seconds = _record_until_warned(tmp_path, sim_args, protocol, channels)
    print(f"{sim_protocol} timer, {protocol} config: warned after {seconds:.1f} s")
    assert seconds < 20
    raw = (tmp_path / "s" / "raw.jsonl").read_text()
    assert raw  # recorded all the same: the bytes are the day
    assert re.search(words, _console_warning(tmp_path, sim_args, protocol, channels))


def _console_warning(tmp_path, sim_args, protocol, channels) -> str:
    """The warning line itself, from a second short recording."""
    sim, port, _truth = start_sim(tmp_path, "--speed", "10", "--first-after", "1",
                                  "--descents", "1", "--hold", "1", *sim_args)  # fmt: skip
    cfg = write_config(tmp_path, port, protocol, channels)
    r = subprocess.run(
        [*station_cmd(), "record", "--config", str(cfg), "--session-dir",
         str(tmp_path / "s2"), "--duration", "8"],
        capture_output=True, text=True, timeout=90,
    )  # fmt: skip
    sim.wait(timeout=30)
    return "\n".join(line for line in r.stdout.splitlines() if line.startswith("warning: "))
