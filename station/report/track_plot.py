"""A picture of the surveyed track: points used and left out, the profile, slope, curvature and
the photocells, as PNG or SVG.

A profile that is only text hides the things a surveyor sees at a glance: a point left out in
the wrong place, a curvature spike, a photocell near the end of the survey. matplotlib (the
field's standard) is imported here only, and only when a picture is asked for, through its
object API (``Figure``): no display backend at the trackside laptop's console, and the day
report gets the picture in memory, without a temporary file.
"""

from __future__ import annotations

import math
import os

import numpy as np

from station.errors import InputError
from station.survey.track import Track

FORMATS = (".png", ".svg")


def plot_track(track: Track, path: str, title: str | None = None) -> str:
    """Draw ``track`` into ``path`` (.png or .svg); returns the path written."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in FORMATS:
        raise InputError(
            f"the picture must be .png or .svg, got {ext or 'no extension'!r}",
            path=path,
            field="--plot",
        )
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError("folder does not exist", path=path, field="--plot")
    if os.path.isdir(path):
        raise InputError("is a folder", path=path, field="--plot")
    fig = track_figure(track, title)
    try:
        fig.savefig(path, dpi=120)
    except OSError as exc:
        raise InputError(
            f"cannot write the picture: {exc.strerror}", path=path, field="--plot"
        ) from None
    return path


def track_figure(track: Track, title: str | None = None):
    """The picture of ``track`` as a matplotlib ``Figure``, drawn in memory (the day report
    embeds it without a file on disk; ``plot_track`` saves it).

    Four panels sharing x: heights (points used, points left out, the profile and the
    photocells), the residuals of the points about the profile with the estimated scatter,
    the slope, and the curvature. Made through the object API (``Figure``, no pyplot): no GUI
    backend is chosen and no global figure is left open.
    """
    from matplotlib.figure import Figure

    prof = track.profile
    x = np.linspace(prof.x_min, prof.x_max, max(200, int(math.ceil(prof.x_max - prof.x_min)) * 4))
    used = [p for p in track.points if p.used]
    out = [p for p in track.points if not p.used]
    fig = Figure(figsize=(10, 9))
    axes = fig.subplots(4, 1, sharex=True, gridspec_kw={"height_ratios": [3, 1.4, 1.4, 1.4]})
    ax_h, ax_r, ax_s, ax_k = axes
    _heights(ax_h, axes, track, x, used, out, title)
    _residuals(ax_r, track, used, out)

    ax_s.plot(x, prof.slope_deg(x), color="C1", lw=1.2)
    ax_s.set_ylabel("slope [°]")
    ax_k.plot(x, prof.curvature(x) * 1000, color="C4", lw=1.2)
    ax_k.axhline(0.0, color="0.3", lw=0.6)
    ax_k.set_ylabel("curvature [1/km]")
    ax_k.set_xlabel("x along the fall line [m]")
    for ax in axes:
        ax.grid(True, lw=0.3)
    fig.tight_layout()
    return fig


def _heights(ax_h, axes, track: Track, x: np.ndarray, used: list, out: list, title: str | None):
    """The heights panel: the profile, the points used and left out, the photocells (their
    lines across every panel) and the title."""
    prof = track.profile
    ax_h.plot(x, prof.h(x), color="C0", lw=1.2, label="profile h(x)")
    ax_h.plot(
        [p.x for p in used],
        [p.y for p in used],
        ".",
        color="C0",
        ms=4,
        label=f"points used ({len(used)})",
    )
    if out:
        ax_h.plot(
            [p.x for p in out],
            [p.y for p in out],
            "x",
            color="C3",
            ms=8,
            mew=2,
            label=f"left out ({len(out)})",
        )
        for p in out:
            ax_h.annotate(
                p.id, (p.x, p.y), textcoords="offset points", xytext=(4, 6), color="C3", fontsize=8
            )
    for pc in track.photocells:
        for ax in axes:
            ax.axvline(pc.x, color="0.6", lw=0.8, ls="--", zorder=0)
        ax_h.plot([pc.x], [pc.y], "v", color="C2", ms=8)
        ax_h.annotate(
            pc.id,
            (pc.x, pc.y),
            textcoords="offset points",
            xytext=(0, 9),
            ha="center",
            color="C2",
            fontsize=8,
        )
    ax_h.set_ylabel("height [m]")
    ax_h.legend(loc="upper right", fontsize=8)
    ax_h.set_title(
        title
        or f"{track.name}: {track.length_m:.1f} m timed, "
        f"{track.drop_m:.1f} m drop, points scatter {track.scatter_m * 1000:.1f} mm"
    )


def _residuals(ax_r, track: Track, used: list, out: list):
    """The residuals panel: the points about the profile in mm, with ±2 × the scatter; a point
    left out is clipped to the edge with its value written."""
    ax_r.axhspan(
        -2 * track.scatter_m * 1000,
        2 * track.scatter_m * 1000,
        color="C0",
        alpha=0.12,
        label="±2 × estimated scatter",
    )
    ax_r.plot([p.x for p in used], [p.residual_m * 1000 for p in used], ".", color="C0", ms=4)
    if out:
        # a gross error would flatten everything else: clip it to the edge and write its value
        lim = 4 * max(track.scatter_m * 1000, 1.0)
        for p in out:
            r = p.residual_m * 1000
            ax_r.plot([p.x], [max(-0.9 * lim, min(0.9 * lim, r))], "x", color="C3", ms=7, mew=2)
            ax_r.annotate(
                f"{p.id} {r:+.0f} mm",
                (p.x, max(-0.9 * lim, min(0.9 * lim, r))),
                textcoords="offset points",
                xytext=(5, -3),
                color="C3",
                fontsize=8,
            )
        ax_r.set_ylim(-lim, lim)
    ax_r.set_ylabel("residual [mm]")
    ax_r.legend(loc="upper right", fontsize=8)
