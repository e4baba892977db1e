"""Simulated theodolite survey of a ski run: a true profile -> Leica GSI-16 file + survey YAML.

The true run is a smooth closed-form profile, steep at the top and flattening out (the shape of
the paper's 342 m / 73 m run). A surveyor sets up a total station at several known stations
beside the run, observes centre-line points every few metres (snow roughness and pole tilt as
target noise) and both posts of each photocell, with realistic instrument noise. The observed
zenith angles include earth curvature and refraction (k = 0.13), so a reduction that corrects
for them recovers the truth.

Run ``python -m station.simulators.survey_sim OUTDIR`` to regenerate ``surveys/demo_run.*``.
"""

from __future__ import annotations

import argparse
import math
import os
from dataclasses import dataclass
from functools import cached_property

import numpy as np

EARTH_R = 6_371_000.0
K_REFRACTION = 0.13
GON = math.pi / 200.0
SIGMA_ANGLE = 1.5 / 3600.0 * math.pi / 180.0  # a 1.5" instrument


@dataclass(frozen=True)
class TrueRun:
    """The true run in a local frame: origin (E0, N0, H0), downhill azimuth, profile h(x)."""

    e0: float = 2480.0
    n0: float = 5130.0
    h0: float = 1710.0
    azimuth_gon: float = 131.25
    x_first: float = 30.0  # first photocell
    spacing: float = 42.0  # between photocells
    n_cells: int = 9
    x_end: float = 400.0  # surveyed span 0 .. x_end

    def slope(self, x: np.ndarray) -> np.ndarray:
        """Slope angle in radians (downhill positive): 17° at the top easing to 8°, a roller."""
        x = np.asarray(x, dtype=float)
        deg = (
            12.0
            + 4.5 * np.cos(math.pi * np.clip(x, 0, 400) / 400.0)
            + 1.2 * np.sin(2 * math.pi * x / 160.0)
        )
        return np.radians(deg)

    @cached_property
    def _height_table(self) -> tuple[np.ndarray, np.ndarray]:
        fine = np.linspace(-50.0, 450.0, 50001)
        dy = -np.tan(self.slope(fine))
        y = np.concatenate([[0.0], np.cumsum(0.5 * (dy[1:] + dy[:-1]) * np.diff(fine))])
        y -= np.interp(0.0, fine, y)
        return fine, y

    def h(self, x: np.ndarray) -> np.ndarray:
        """Height: integral of −tan(slope), by fine quadrature (the truth for the tests)."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        fine, y = self._height_table
        return self.h0 + np.interp(x, fine, y)

    def dslope(self, x: np.ndarray) -> np.ndarray:
        """d(slope)/dx in radians per metre (closed form of :meth:`slope`, inside 0..400 m)."""
        x = np.asarray(x, dtype=float)
        ddeg = -4.5 * math.pi / 400.0 * np.sin(math.pi * x / 400.0) + 1.2 * (
            2 * math.pi / 160.0
        ) * np.cos(2 * math.pi * x / 160.0)
        return np.radians(ddeg)

    def profile(self, x_offset: float = 0.0):
        """The true profile as a :class:`station.survey.track.Profile` in a frame whose x is the
        true x minus ``x_offset`` (a surveyed track's origin lies ``x_offset`` down the run)."""
        from station.survey.track import Profile

        def dh(x):
            return -np.tan(self.slope(np.asarray(x, float) + x_offset))

        def d2h(x):
            xt = np.asarray(x, float) + x_offset
            return -self.dslope(xt) / np.cos(self.slope(xt)) ** 2

        return Profile(
            h=lambda x: self.h(np.asarray(x, float) + x_offset),
            dh=dh,
            d2h=d2h,
            x_min=-x_offset,
            x_max=self.x_end - x_offset,
        )

    @property
    def cell_x(self) -> np.ndarray:
        return self.x_first + self.spacing * np.arange(self.n_cells)

    def to_en(self, x: np.ndarray, lateral: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local (x along the fall line, lateral + left) -> grid E, N."""
        az = self.azimuth_gon * GON
        ue, un = math.sin(az), math.cos(az)
        le, ln = -un, ue
        return self.e0 + x * ue + lateral * le, self.n0 + x * un + lateral * ln


def _word16(wi: str, info: str, value: int | str) -> str:
    """A GSI-16 word: WI, 4 info characters, sign, 16 data characters."""
    if isinstance(value, str):
        data = value.rjust(16, "0")[-16:]
        sign = "+"
    else:
        sign = "-" if value < 0 else "+"
        data = str(abs(int(value))).rjust(16, "0")
    return f"{wi}{info}{sign}{data}"


Station = tuple[str, float, float, float, float]  # id, E, N, H, instrument height
Target = tuple[str, float, float, float, float, float]  # id, x, E, N, H, reflector height


class _FieldBook:
    """The GSI-16 blocks in the order the instrument records them, with its noise."""

    def __init__(self, rng: np.random.Generator, blunders: dict[str, float]) -> None:
        self.rng = rng
        self.blunders = blunders
        self.lines: list[str] = []

    def add(self, words: list[str]) -> None:
        self.lines.append("*" + " ".join(words) + " ")

    def setup(self, station: Station) -> None:
        """A station setup: its known coordinates and instrument height."""
        sid, se, sn, sh, hi = station
        self.add(
            [
                _word16("11", f"{len(self.lines) + 1:04d}", sid),
                _word16("84", "..46", round(se * 1e4)),
                _word16("85", "..46", round(sn * 1e4)),
                _word16("86", "..46", round(sh * 1e4)),
                _word16("88", "..46", round(hi * 1e4)),
            ]
        )

    def observe(
        self, pid: str, e: float, n: float, h: float, st: tuple[float, float, float, float],
        hr: float,
    ) -> None:  # fmt: skip
        """One target observed from setup ``st``: azimuth, zenith angle, slope distance."""
        se, sn, sh, hi = st
        de, dn = e - se, n - sn
        hd = math.hypot(de, dn)
        dh = h + hr - (sh + hi)
        # what the instrument sees: the target lowered by curvature, raised by refraction
        dh_seen = dh - (1.0 - K_REFRACTION) * hd * hd / (2.0 * EARTH_R)
        sd = math.hypot(hd, dh_seen)
        zen = math.atan2(hd, dh_seen)
        az = math.atan2(de, dn) % (2 * math.pi)
        sd += self.rng.normal(0.0, 1e-3 + 1.5e-6 * sd)
        zen += self.rng.normal(0.0, SIGMA_ANGLE)
        az += self.rng.normal(0.0, SIGMA_ANGLE)
        self.add(
            [
                _word16("11", f"{len(self.lines):04d}", pid),
                _word16("21", ".322", round((az % (2 * math.pi)) / GON * 1e5)),
                _word16("22", ".322", round(zen / GON * 1e5)),
                _word16("31", "..06", round(sd * 1e4)),
                _word16("87", "..16", round((hr + self.blunders.get(pid, 0.0)) * 1e4)),
            ]
        )


def _stations(run: TrueRun, station_x: list[float]) -> list[Station]:
    """Instrument stations 28-35 m to the left of the fall line, known coordinates (GNSS)."""
    stations = []
    for i, sx in enumerate(station_x):
        lat = -30.0 - 2.0 * i
        e, n = run.to_en(np.array([sx]), np.array([lat]))
        h = float(run.h(np.array([sx]))[0]) + 1.0  # a small mound beside the run
        stations.append((f"ST{i + 1}", float(e[0]), float(n[0]), h, 1.55 + 0.05 * i))
    return stations


def _targets(
    run: TrueRun, rng: np.random.Generator, cell_ids: list[str], spacing: float,
    roughness: float, post_sd: float,
) -> list[Target]:  # fmt: skip
    """The true points, placed once: centre-line points with lateral jitter and snow roughness,
    and both posts of each photocell, ±4 m beside the track with a beam across the run."""
    profile_x = np.arange(0.0, run.x_end + 1e-9, spacing)
    targets: list[Target] = []
    for j, px in enumerate(profile_x):
        e, n = run.to_en(np.array([px]), np.array([rng.normal(0.0, 0.3)]))
        h = float(run.h(np.array([px]))[0]) + rng.normal(0.0, roughness)
        targets.append((f"P{j:03d}", float(px), float(e[0]), float(n[0]), h, 2.0))
    for cid, cx in zip(cell_ids, run.cell_x, strict=True):
        for side, lat in (("L", 4.0), ("R", -4.0)):
            e, n = run.to_en(np.array([cx + rng.normal(0, post_sd)]), np.array([lat]))
            h = float(run.h(np.array([cx]))[0]) + rng.normal(0.0, 0.02)
            targets.append((f"{cid}{side}", float(cx), float(e[0]), float(n[0]), h, 1.3))
    return targets


def simulate_survey(
    run: TrueRun,
    seed: int = 7,
    spacing: float = 5.0,
    roughness: float = 0.005,
    blunders: dict[str, float] | None = None,
    post_sd: float = 0.01,
) -> tuple[str, list[str]]:
    """Observe the run; return the GSI-16 text and the photocell ids.

    ``spacing``: metres between centre-line points; ``roughness``: standard deviation (m) of
    their heights about the true profile (snow, pole tilt); ``blunders``: point id -> error (m)
    of the reflector height *booked* for it (the prism stood at 2.0 m, the book says 2.0 + e),
    so that point comes out e too low; ``post_sd``: standard deviation (m) of each photocell
    post's position along the run about the beam's true x.
    """
    rng = np.random.default_rng(seed)
    book = _FieldBook(rng, blunders or {})
    station_x = [60.0, 200.0, 340.0]
    stations = _stations(run, station_x)
    cell_ids = [f"PC{i + 1}" for i in range(run.n_cells)]
    targets = _targets(run, rng, cell_ids, spacing, roughness, post_sd)
    for station, sx in zip(stations, station_x, strict=True):
        book.setup(station)
        st = station[1:]
        for pid, tx, e, n, h, hr in targets:
            if abs(tx - sx) <= 80.0:  # each setup covers the run 80 m either side
                book.observe(pid, e, n, h, st, hr)
    return "\r\n".join(book.lines) + "\r\n", cell_ids


SURVEY_YAML = """\
# Demo run: a 340 m timed section with nine photocells, surveyed from three setups.
# Produced by `python -m station.simulators.survey_sim surveys` (the true profile: its TrueRun).
name: Demo run (simulated survey)
observations: demo_run.gsi
refraction_k: 0.13
precision:
  angle_arcsec: 1.5
  distance_mm: 1.0
  distance_ppm: 1.5
  target_mm: 5
# the profile is every point named P...; each photocell is the mean of its two posts
profile_pattern: "^P\\\\d+$"
photocells:
{cells}
"""


def write_demo(
    outdir: str, seed: int = 7, stem: str = "demo_run", **survey: object
) -> tuple[str, str]:
    """Write ``stem``.gsi and ``stem``.yaml into ``outdir``; ``survey`` goes to
    :func:`simulate_survey` (spacing, roughness, blunders)."""
    run = TrueRun()
    gsi, cells = simulate_survey(run, seed, **survey)  # type: ignore[arg-type]
    os.makedirs(outdir, exist_ok=True)
    gsi_path = os.path.join(outdir, f"{stem}.gsi")
    yaml_path = os.path.join(outdir, f"{stem}.yaml")
    with open(gsi_path, "w", encoding="ascii", newline="") as fh:
        fh.write(gsi)
    cell_lines = "\n".join(f"  - {{id: {c}, points: [{c}L, {c}R]}}" for c in cells)
    with open(yaml_path, "w", encoding="utf-8") as fh:
        fh.write(SURVEY_YAML.format(cells=cell_lines).replace("demo_run.gsi", f"{stem}.gsi"))
    return gsi_path, yaml_path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--seed", type=int, default=7)
    args = ap.parse_args(argv)
    for path in write_demo(args.outdir, args.seed):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
