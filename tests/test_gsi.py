"""Leica GSI reading and polar reduction, against the real files' published values."""

from __future__ import annotations

import math

import pytest

from station.errors import InputError
from station.survey.gsi import decode_word, parse_gsi, read_gsi
from station.survey.polar import (
    Setup,
    curvature_refraction,
    interpret_gsi,
    reduce_all,
    reduce_observation,
)


def test_gsi16_dms_first_point_matches_published(real):
    blocks = read_gsi(str(real / "leica_gsi" / "leica_gsi16_gurob.gsi"))
    obs = interpret_gsi(blocks, "gurob")
    p = reduce_observation(obs.observations[0], k=None)
    assert p.point == "GDEM5415"
    # Total Open Station's tests: station (0, 0, 0), no curvature/refraction correction
    assert p.e == pytest.approx(8.0757244, abs=1e-7)
    assert p.n == pytest.approx(11.21674196, abs=1e-7)
    assert p.h == pytest.approx(-0.2890493, abs=1e-7)


def test_rilievo_bare_cr_file_has_23_points_and_third_matches(real):
    path = real / "leica_gsi" / "RILIEVO.gsi"
    assert b"\n" not in path.read_bytes()  # the file really ends its lines with bare CR
    obs = interpret_gsi(read_gsi(str(path)), "rilievo")
    points = reduce_all(obs, k=None)
    assert len(points) == 23
    p = points[2]
    assert p.point == "102"
    assert (p.e, p.n, p.h) == pytest.approx((4.49963916, -2.51722711, -0.30665937), abs=1e-7)


def test_ertola_reproduces_the_instruments_own_coordinates(real):
    """380 blocks of the first setup (500, 500, 0, hi 1.540) and all 25 of setup STAZLIB3."""
    blocks = read_gsi(str(real / "leica_gsi" / "leica_gsi8_ertola.gsi"))
    first = Setup("S0", e=500.0, n=500.0, h=0.0, instrument_height=1.540)
    obs = interpret_gsi(blocks, "ertola", default_setup=first)
    points = reduce_all(obs, k=None)
    assert points[0].instrument_enh == pytest.approx((515.836, 525.871, 3.079))

    def matches(p) -> bool:
        return p.instrument_enh is not None and all(
            abs(a - b) <= 0.0015 for a, b in zip((p.e, p.n, p.h), p.instrument_enh, strict=True)
        )

    default = [p for p in points if p.setup == "S0"]
    assert sum(matches(p) for p in default) == 380
    lib3 = [p for p in points if p.setup == "STAZLIB3" and p.instrument_enh is not None]
    assert len(lib3) == 25 and all(matches(p) for p in lib3)
    # station block: coordinates, instrument height; its WI 25 is recorded, not re-applied
    st = next(s for s in obs.setups if s.station == "STAZLIB3")
    assert (st.e, st.n, st.h, st.instrument_height) == pytest.approx(
        (519.659, 465.244, -0.588, 1.35)
    )
    assert sum(matches(p) for p in points) >= 497


def test_curvature_and_refraction_correction():
    assert curvature_refraction(342.0, 0.13) == pytest.approx(7.99e-3, abs=0.01e-3)
    assert curvature_refraction(100.0, 0.13) == pytest.approx(0.68e-3, abs=0.01e-3)
    assert curvature_refraction(342.0, None) == 0.0


@pytest.mark.parametrize(
    ("word", "value"),
    [
        ("21.322+10000000", math.pi / 2),  # 100 gon
        ("21.323+09000000", math.pi / 2),  # 90.00000 decimal degrees
        ("21.324+09000000", math.pi / 2),  # 90°00'00" DDD.MMSSs
        ("21.324+03545100", math.radians(35 + 45 / 60 + 10 / 3600)),
        ("21.325+16000000", math.pi / 2),  # 1600 mil
        ("31..00+00030485", 30.485),  # m, 1 mm
        ("31..06+00304850", 30.485),  # m, 0.1 mm
        ("31..08+03048500", 30.485),  # m, 0.01 mm
        ("31..01+00100000", 30.48),  # 100 ft
        ("31..07+01000000", 30.48),  # 100 ft in 1/10000 ft
        ("86..40-00000588", -0.588),
    ],
)
def test_unit_digits(word, value):
    assert decode_word(word).value == pytest.approx(value, rel=1e-12)


def test_gsi16_word_decodes_like_gsi8():
    b8 = parse_gsi("110001+00000001 22.322+09364360 31..00+00030485 \r\n")[0]
    b16 = parse_gsi("*110001+0000000000000001 22.322+0000000009364360 31..00+0000000000030485\n")[0]
    assert b8.point_id == b16.point_id == "1"
    assert b8.value("22") == b16.value("22")
    assert b8.value("31") == b16.value("31") == pytest.approx(30.485)


@pytest.mark.parametrize(
    ("text", "field", "fragment"),
    [
        ("110001+00000001 21.322+0349694X\n", "WI 21 (Hz)", "not a number"),
        ("110001+00000001 21.329+03496940\n", "WI 21 (Hz)", "unknown unit digit '9'"),
        ("110001+00000001 31..02+00030485\n", "WI 31 (slope distance)", "needs a length"),
        ("110001+00000001 21.322+034969\n", "WI 21 (Hz)", "characters"),
        ("110001+00000001 22.324+09999999\n", "WI 22 (zenith angle)", "DDD.MMSSs"),
        ("110001+00000001 21.322*03496940\n", "WI 21 (Hz)", "sign"),
    ],
)
def test_malformed_words_name_line_and_field(text, field, fragment):
    with pytest.raises(InputError) as err:
        parse_gsi("110000+00000000 87..10+00001500\n" + text, "run.gsi")
    msg = str(err.value)
    assert msg.startswith("run.gsi:2: field " + field)
    assert fragment in msg
    assert "\n" not in msg


def test_bare_cr_line_numbers_count_each_line_end():
    text = (
        "\r110001+00000100 21.102+11545200 22.102+09885300 31..00+00000000\r\r"
        "\r110002+0000010X 21.102+1154520\r"
    )
    with pytest.raises(InputError) as err:
        parse_gsi(text, "old.gsi")
    assert str(err.value).startswith("old.gsi:5:")


def test_a_file_that_starts_with_its_station_block_has_no_default_setup():
    """Found by a new-user trial: the demo GSI (ST1 on line 1) was said to have 4 setups,
    one of them a 'default' at 0, 0, 0 that no observation used."""
    from pathlib import Path

    demo = Path(__file__).resolve().parent.parent / "surveys" / "demo_run.gsi"
    obs = interpret_gsi(read_gsi(str(demo)), "demo")
    assert [s.station for s in obs.setups] == ["ST1", "ST2", "ST3"]


def test_observations_before_any_station_block_keep_the_default_setup(real):
    """The Total Open Station file has no station block: its observations are reduced from
    the default station at 0, 0, 0, which must stay listed."""
    blocks = read_gsi(str(real / "leica_gsi" / "leica_gsi16_gurob.gsi"))
    obs = interpret_gsi(blocks, "gurob")
    used = {o.setup.station for o in obs.observations}
    assert {s.station for s in obs.setups} >= used and obs.setups
