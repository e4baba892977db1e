"""``station survey``: a survey reduced to the track profile and its photocells, or a bare
observation file's points listed for checking."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from station.cli.common import _print_json, _warn, open_output, output_path
from station.errors import InputError

if TYPE_CHECKING:  # the survey modules import numpy and scipy: loaded when a command runs
    import numpy as np

    from station.model.physics import Gravity
    from station.survey.load import Survey
    from station.survey.track import Track


def cmd_survey_points(args: argparse.Namespace, survey: Survey) -> int:
    """A bare observation file has no photocells: list the reduced points for checking."""
    pts = list(survey.points.values())
    if args.csv:
        from station import csvfiles

        with open_output(args.csv, "--csv") as fh:
            w = csvfiles.writer(fh)
            w.writerow(["point", "e", "n", "h", "sigma_h_m", "setup", "line"])
            for p in pts:
                w.writerow([p.point, f"{p.e:.4f}", f"{p.n:.4f}", f"{p.h:.4f}", f"{p.sigma_h:.4f}",
                            p.setup, p.line])  # fmt: skip
    if args.json:
        _print_json(
            {
                "points": [
                    {
                        "id": p.point,
                        "e": p.e,
                        "n": p.n,
                        "h": p.h,
                        "sigma_h_m": p.sigma_h,
                        "setup": p.setup,
                        "line": p.line,
                    }  # fmt: skip
                    for p in pts
                ],
                "setups": [_setup_json(survey, s) for s in survey.setups],
                "format": survey.format,
                "warnings": survey.warnings,
            }
        )
        return 0
    print(f"observations  {args.survey}: {len(pts)} points from {len(survey.setups)} setup(s)"
          + (f", {survey.format}" if survey.format else ""))  # fmt: skip
    if survey.setups:
        _print_setups(survey)
    print()
    print(f"{'point':<12}{'E':>12}{'N':>12}{'H':>10}{'σH [mm]':>9}  setup")
    for p in pts:
        print(
            f"{p.point:<12}{p.e:>12.3f}{p.n:>12.3f}{p.h:>10.3f}{p.sigma_h * 1000:>9.1f}  {p.setup}"
        )
    for w in survey.warnings:
        _warn(w)
    before = any(s.station == "default" and s.line is None for s in survey.setups)
    _warn(
        "a bare observation file has no photocells"
        + (
            "; blocks before the first station block were reduced from station 0, 0, 0 with "
            "instrument height 0"
            if before
            else ""
        )
        + ". Write a survey YAML (surveys/README.md) to name the photocells"
        + (" and the first setup" if before else "")
        + " and get the track"
    )
    return 0


def _setup_json(survey: Survey, s: Any) -> dict[str, Any]:
    """One setup for --json; placed by the network: orientation, ties and residual RMS too."""
    out = {"station": s.station, "e": s.e, "n": s.n, "h": s.h,
           "instrument_height": s.instrument_height, "line": s.line}  # fmt: skip
    placed = {p.station: p for p in survey.network.setups} if survey.network else {}
    p = placed.get(s.station)
    if p is not None:
        out["orientation_gon"] = s.orientation * 200 / math.pi
        out.update(fixed=p.fixed, tie_observations=p.ties, rms_xy_m=p.rms_xy_m, rms_h_m=p.rms_h_m)
    return out


def _print_setups(survey: Survey) -> None:
    """The setups; placed by the network adjustment: orientation and residuals too."""
    net = {p.station: p for p in survey.network.setups} if survey.network else {}
    extra = f"{'ω [gon]':>10}{'ties':>6}{'RMS E,N/H [mm]':>16}" if net else ""
    print(f"{'setup':<12}{'E':>12}{'N':>12}{'H':>10}{'hi':>7}{extra}  line")
    for s in survey.setups:
        line = "" if s.line is None else str(s.line)
        more = ""
        p = net.get(s.station)
        if p is not None:
            rms = (
                "fixed"
                if p.fixed and not p.ties
                else f"{p.rms_xy_m * 1e3:.1f}/{p.rms_h_m * 1e3:.1f}"
            )
            more = f"{s.orientation * 200 / math.pi:>10.4f}{p.ties:>6}{rms:>16}"
        print(
            f"{s.station:<12}{s.e:>12.3f}{s.n:>12.3f}{s.h:>10.3f}"
            f"{s.instrument_height:>7.3f}{more}  {line}"
        )


def cmd_survey(args: argparse.Namespace) -> int:
    import numpy as np  # here, not at the top: `station --help` and other commands need no numpy

    output_path(args.csv, "--csv")
    from station.model.physics import gravity_for
    from station.survey.load import load_survey
    from station.survey.track import build_track

    survey = load_survey(args.survey)
    if survey.bare:
        if args.plot:
            raise InputError(
                "a bare observation file has no photocells and no track to draw; write a "
                "survey YAML (surveys/README.md)",
                path=args.survey,
            )
        return cmd_survey_points(args, survey)
    track = build_track(survey)
    grav = gravity_for(track)
    prof = track.profile
    xg = np.arange(math.ceil(prof.x_min), math.floor(prof.x_max) + 1e-9, 1.0)
    yg, sg, kg = prof.h(xg), prof.slope_deg(xg), prof.curvature(xg)
    used = [p for p in track.points if p.used]
    sig = float(np.sqrt(np.mean([p.sigma**2 for p in used])))
    if args.plot:
        from station.report.track_plot import plot_track

        plot_track(track, args.plot)
        if args.json:
            _warn(f"track picture written to {args.plot}")
    if args.csv:
        from station import csvfiles

        with open_output(args.csv, "--csv") as fh:
            w = csvfiles.writer(fh)
            w.writerow(["x_m", "y_m", "slope_deg", "curvature_1_per_m"])
            for row in zip(xg, yg, sg, kg, strict=True):
                w.writerow([f"{row[0]:.3f}", f"{row[1]:.4f}", f"{row[2]:.4f}", f"{row[3]:.6f}"])
    if args.json:
        _print_json(_track_json(track, grav, sig, xg, yg, sg, kg))
    else:
        _print_track(args, track, grav, sig, kg)
    return 0


def _track_json(
    track: Track,
    grav: Gravity,
    sig: float,
    xg: np.ndarray,
    yg: np.ndarray,
    sg: np.ndarray,
    kg: np.ndarray,
) -> dict[str, Any]:
    """``station survey --json``: the track, its QA values, the profile every metre."""
    return {
        "name": track.name,
        "length_m": track.length_m,
        "drop_m": track.drop_m,
        "residual_rms_m": track.residual_rms_m,
        "expected_sigma_m": sig,
        "scatter_m": track.scatter_m,
        "declared_sigma_m": track.declared_sigma_m,
        "spline_edf": track.spline_edf,
        "points_left_out": [p.id for p in track.points if not p.used],
        "azimuth_deg": track.azimuth_deg,
        "gravity_ms2": grav.value,
        "gravity_source": grav.source,
        "latitude_deg": track.latitude_deg,
        "photocells": [
            {
                "id": pc.id,
                "x": pc.x,
                "y": pc.y,
                "slope_deg": pc.slope_deg,
                "lateral_m": pc.lateral_m,
            }
            for pc in track.photocells
        ],
        "profile": {
            "x": xg.tolist(),
            "y": yg.tolist(),
            "slope_deg": sg.tolist(),
            "curvature": kg.tolist(),
        },
        "points": [
            {
                "id": p.id,
                "x": p.x,
                "y": p.y,
                "sigma_m": p.sigma,
                "lateral_m": p.lateral_m,
                "residual_m": p.residual_m,
                "used": p.used,
            }
            for p in track.points
        ],
        "warnings": track.warnings,
    }


def _print_track(
    args: argparse.Namespace, track: Track, grav: Gravity, sig: float, kg: np.ndarray
) -> None:
    """``station survey``'s text: the track, its QA values, the photocells, the warnings."""
    prof = track.profile
    used = [p for p in track.points if p.used]
    lat = [abs(p.lateral_m) for p in used]
    print(f"survey   {track.name}  ({args.survey})")
    if track.photocells:
        print(
            f"timed    {track.length_m:.2f} m along the track, {track.drop_m:.2f} m drop, "
            f"{len(track.photocells)} photocells"
        )
    print(
        f"profile  {len(used)} points over x = {prof.x_min:.1f} .. {prof.x_max:.1f} m, "
        f"axis azimuth {track.azimuth_deg:.2f}°, largest lateral offset {max(lat):.2f} m"
    )
    print(
        f"spline   points scatter {track.scatter_m * 1000:.1f} mm about the profile "
        f"(estimated from the points; declared σ {sig * 1000:.1f} mm), "
        f"residual RMS {track.residual_rms_m * 1000:.1f} mm, "
        f"{track.spline_edf:.0f} effective parameters"
    )
    left_out = [p.id for p in track.points if not p.used]
    if left_out:
        print(f"left out {len(left_out)} point(s): {', '.join(left_out)} (see warnings)")
    print(f"curvature {kg.min():+.5f} .. {kg.max():+.5f} 1/m")
    print(f"gravity  {grav.describe()}")
    if track.photocells:
        print()
        print(f"{'photocell':<10}{'x [m]':>10}{'y [m]':>11}{'slope [°]':>11}{'lateral [m]':>13}")
        for pc in track.photocells:
            print(
                f"{pc.id:<10}{pc.x:>10.2f}{pc.y:>11.2f}{pc.slope_deg:>11.2f}{pc.lateral_m:>+13.2f}"
            )
    if args.plot:
        print(f"picture  {args.plot}")
    for w in track.warnings:
        _warn(w)


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("survey", help="reduce a survey to the track profile and photocells")
    p.add_argument(
        "survey",
        help="survey YAML, or a bare observation file (Leica GSI, Sokkia SDR, Topcon GTS-7, "
        "LandXML, Carlson RW5) or points CSV",
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.add_argument("--csv", metavar="OUT", help="write the profile (every metre) as CSV")
    p.add_argument(
        "--plot",
        metavar="FILE",
        help="draw the points (used and left out), profile, slope, curvature and photocells "
        "into FILE (.png or .svg)",
    )
    p.set_defaults(func=cmd_survey)
