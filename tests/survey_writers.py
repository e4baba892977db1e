"""Test-only writers of instrument files (SDR33, GTS-7, GSI-16, RW5, LandXML) from an
ObservationSet, for round trips through the station's readers. Written from the formats'
documented layouts (see the reader modules' docstrings), not from the readers' code."""

from __future__ import annotations

import math

from station.survey.polar import Observation, ObservationSet, Setup

GON = 200.0 / math.pi
DEG = 180.0 / math.pi


def _f16(v: float) -> str:
    text = f"{v:.8f}"
    if len(text) > 16:
        text = f"{v:.{max(0, 16 - len(text.split('.')[0]) - 1)}f}"
    return text[:16].ljust(16)


def _id16(pid: str) -> str:
    return pid.rjust(16)


def _by_setup(obs: ObservationSet) -> list[tuple[Setup, list[Observation]]]:
    out: list[tuple[Setup, list[Observation]]] = []
    for o in obs.observations:
        if not out or out[-1][0] is not o.setup:
            out.append((o.setup, []))
        out[-1][1].append(o)
    return out


def sdr33(
    obs: ObservationSet, gon: bool = True, north_first: bool = True, clockwise: bool = True
) -> bytes:
    """An SDR33 job as a serial download: STX first, ETX and a checksum last, CRLF."""
    angle = GON if gon else DEG
    flags = f"{2 if gon else 1}111{1 if north_first else 2}{1 if clockwise else 2}"
    lines = ["\x02" + "00NMSDR33 V04-04.02     00-000-00 00:00 " + flags]
    lines.append("10NMJOB1            121111")
    lines.append("13NMcomment: Schnee \u00b0C")
    for s, group in _by_setup(obs):
        c1, c2 = (s.n, s.e) if north_first else (s.e, s.n)
        lines.append(
            "02TP"
            + _id16(s.station)
            + _f16(c1)
            + _f16(c2)
            + _f16(s.h)
            + _f16(s.instrument_height)
            + "ST".ljust(16)
        )
        if s.orientation:
            lines.append(
                "07TP" + _id16(s.station) + _id16("BS") + _f16(s.orientation * angle) + _f16(0.0)
            )
        th = None
        for o in group:
            if o.reflector_height != th:
                th = o.reflector_height
                lines.append("03NM" + _f16(th))
            hz = (o.hz * angle) % (400.0 if gon else 360.0)
            if not clockwise:
                hz = ((400.0 if gon else 360.0) - hz) % (400.0 if gon else 360.0)
            sd = o.slope_distance if o.slope_distance is not None else 0.0
            lines.append(
                "09F1"
                + _id16(s.station)
                + _id16(o.point)
                + _f16(sd)
                + _f16(o.zenith * angle)
                + _f16(hz)
                + "P".ljust(16)
            )
    lines.append("\x03" + "12345")
    return ("\r\n".join(lines) + "\r\n").encode("cp1252")


def packed_dms(rad: float) -> str:
    """Radians → DDD.MMSSs (tenths of seconds)."""
    tenths = round(abs(math.degrees(rad)) * 36000.0)
    d, rest = divmod(tenths, 36000)
    m, t = divmod(rest, 600)
    return f"{'-' if rad < 0 else ''}{d}.{m:02d}{t:03d}"


def gts7(obs: ObservationSet) -> str:
    lines = ["GTS-700 v1", "JOB     test,", "UNITS   M,D"]
    for s, group in _by_setup(obs):
        lines += [
            f"STN     {s.station},{s.instrument_height:.4f},",
            f"XYZ     {s.e:.4f},{s.n:.4f},{s.h:.4f}",
            f"BKB     BS,{packed_dms(s.orientation % (2 * math.pi))},0.00000",
        ]
        for o in group:
            lines.append(f"SS      {o.point},{o.reflector_height:.4f},code")
            lines.append(
                f"SD      {packed_dms(o.hz % (2 * math.pi))},{packed_dms(o.zenith)},"
                f"{o.slope_distance:.4f}"
            )
    return "\n".join(lines) + "\n"


def _w16(wi: str, info: str, value: float | str) -> str:
    if isinstance(value, str):
        return f"{wi}{info}+{value.rjust(16, '0')}"
    return f"{wi}{info}{'-' if value < 0 else '+'}{abs(round(value)):016d}"


def gsi16_network(obs: ObservationSet) -> str:
    """GSI-16 with a code block (41/42/43) per setup and no setup coordinates."""
    lines = []
    for n, (s, group) in enumerate(_by_setup(obs), start=1):
        lines.append(
            "*"
            + " ".join(
                [
                    _w16("41", f"{n:04d}", "21"),
                    _w16("42", "....", s.station),
                    _w16("43", "....", s.instrument_height * 1000),
                ]
            )
        )
        for i, o in enumerate(group, start=1):
            lines.append(
                "*"
                + " ".join(
                    [
                        _w16("11", f"{i:04d}", o.point),
                        _w16("21", ".322", (o.hz * GON % 400.0) * 1e5),
                        _w16("22", ".322", o.zenith * GON * 1e5),
                        _w16("31", "..06", (o.slope_distance or 0.0) * 1e4),
                        _w16("87", "..16", o.reflector_height * 1e4),
                    ]
                )
            )
    return "\r\n".join(lines) + "\r\n"


def rw5(obs: ObservationSet) -> str:
    lines = ["JB,NMtest,DT01-01-2026,TM12:00:00", "MO,AD0,UN1,SF1.00000000,EC0,EO0.0,AU0"]
    for s, group in _by_setup(obs):
        lines.append(f"OC,OP{s.station},N {s.n:.4f},E {s.e:.4f},EL {s.h:.4f},--")
        lines.append(
            f"BK,OP{s.station},BPBS,BS{packed_dms(s.orientation % (2 * math.pi))},BC0.00000"
        )
        hr = None
        for o in group:
            if o.reflector_height != hr:
                hr = o.reflector_height
                lines.append(f"LS,HI{s.instrument_height:.4f},HR{hr:.4f}")
            lines.append(
                f"SS,OP{s.station},FP{o.point},AR{packed_dms(o.hz % (2 * math.pi))},"
                f"ZE{packed_dms(o.zenith)},SD{o.slope_distance:.4f},--P"
            )
    return "\n".join(lines) + "\n"


def landxml(obs: ObservationSet) -> str:
    """LandXML 1.2 in gon: each setup's InstrumentPoint by coordinates, raw observations."""
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<LandXML xmlns="http://www.landxml.org/schema/LandXML-1.2" version="1.2">',
        '<Units><Metric linearUnit="meter" angularUnit="grads"/></Units>',
        "<CgPoints>",
    ]
    groups = _by_setup(obs)
    for s, _ in groups:
        out.append(f'<CgPoint name="{s.station}">{s.n:.5f} {s.e:.5f} {s.h:.5f}</CgPoint>')
    out += ["</CgPoints>", "<Survey>"]
    for n, (s, _group) in enumerate(groups):
        out.append(
            f'<InstrumentSetup id="IS{n}" stationName="{s.station}" '
            f'instrumentHeight="{s.instrument_height:.5f}">'
        )
        out.append(f'<InstrumentPoint pntRef="{s.station}"/>')
        out.append("</InstrumentSetup>")
    out.append('<ObservationGroup id="OG1">')
    for n, (s, group) in enumerate(groups):
        for o in group:
            out.append(
                f'<RawObservation setupID="IS{n}" targetHeight="{o.reflector_height}" '
                f'horizAngle="{(o.hz + s.orientation) * GON % 400:.7f}" '
                f'zenithAngle="{o.zenith * GON:.7f}" '
                f'slopeDistance="{o.slope_distance:.5f}">'
                f'<TargetPoint name="{o.point}"/></RawObservation>'
            )
    out += ["</ObservationGroup>", "</Survey>", "</LandXML>"]
    return "\n".join(out) + "\n"
