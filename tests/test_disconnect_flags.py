"""A descent's flags say a broken connection once, in a few words: the tryout saw pyserial's
sentence twice in one table cell ("timer disconnected (device reports readiness to read but
returned no data …); timer disconnected (…)"). The raw log keeps the full message."""

from __future__ import annotations

from station.timing.assembly import DETAIL_CHARS, DescentAssembler, short_detail
from station.timing.impulses import Impulse

PCS = ["PC1", "PC2", "PC3"]
CH = {"C0": "PC1", "C1": "PC2", "C2": "PC3"}
POS = [0.0, 40.0, 80.0]
S = 1_000_000
PYSERIAL = (
    "device reports readiness to read but returned no data (device disconnected or multiple "
    "access on port?)"
)


def test_a_repeated_disconnect_is_flagged_once_and_short():
    asm = DescentAssembler(PCS, CH, positions_m=POS)
    asm.feed(Impulse("C0", 100 * S, 100, "", "", None, ""), 1)
    asm.disconnected(PYSERIAL)
    asm.disconnected(PYSERIAL)  # reconnected, and lost again within the same descent
    assert asm.open[0].flags == ["timer disconnected (no data: unplugged or in use)"]
    asm.disconnected("[Errno 5] Input/output error")  # a different message is news
    assert len(asm.open[0].flags) == 2


def test_any_port_message_is_cut_to_a_few_words():
    assert short_detail("read failed") == "read failed"
    assert short_detail("could not open port /dev/ttyUSB0 (No such file)") == (
        "could not open port /dev/ttyUSB0"
    )
    long = "x" * 200
    assert len(short_detail(long)) == DETAIL_CHARS and short_detail(long).endswith("…")
