"""Coordinate input: a survey YAML naming ``points: FILE.csv`` (id,e,n,h[,sigma_h])."""

from __future__ import annotations

import numpy as np
import pytest

from station.errors import InputError
from station.simulators.survey_sim import TrueRun
from station.survey.load import load_survey
from station.survey.track import build_track


def _rows(run: TrueRun, spacing: float = 5.0) -> list[tuple[str, float, float, float]]:
    rng = np.random.default_rng(11)
    rows = []
    for j, x in enumerate(np.arange(0.0, run.x_end + 1e-9, spacing)):
        e, n = run.to_en(np.array([x]), np.array([rng.normal(0, 0.3)]))
        h = float(run.h(np.array([x]))[0]) + rng.normal(0, 0.01)
        rows.append((f"P{j:03d}", float(e[0]), float(n[0]), h))
    for k, cx in enumerate(run.cell_x):
        for side, lat in (("L", 4.0), ("R", -4.0)):
            e, n = run.to_en(np.array([cx]), np.array([lat]))
            rows.append((f"PC{k + 1}{side}", float(e[0]), float(n[0]), 0.0 + run.h(cx)[0]))
    return rows


def _write(tmp_path, sep=",", decimal=".", sigma=True, yaml_extra=""):
    run = TrueRun()
    head = sep.join(["id", "e", "n", "h"] + (["sigma_h"] if sigma else []))
    lines = [head]
    for pid, e, n, h in _rows(run):
        vals = [f"{e:.4f}", f"{n:.4f}", f"{h:.4f}"] + (["0.012"] if sigma else [])
        lines.append(sep.join([pid] + [v.replace(".", decimal) for v in vals]))
    (tmp_path / "pts.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    cells = "\n".join(f"  - {{id: PC{k}, points: [PC{k}L, PC{k}R]}}" for k in range(1, 10))
    yaml = tmp_path / "run.yaml"
    yaml.write_text(
        f'name: GNSS run\npoints: pts.csv\nprofile_pattern: "^P\\\\d+$"\n{yaml_extra}'
        f"photocells:\n{cells}\n"
    )
    return yaml, run


@pytest.mark.parametrize(("sep", "decimal"), [(",", "."), (";", ","), ("\t", ".")])
def test_a_coordinate_list_gives_the_track(tmp_path, sep, decimal):
    yaml, run = _write(tmp_path, sep, decimal)
    track = build_track(load_survey(str(yaml)))
    assert track.photocell_ids == [f"PC{k}" for k in range(1, 10)]
    assert [pc.x for pc in track.photocells] == pytest.approx(
        run.cell_x - run.cell_x[0] + 30, abs=0.02
    )
    assert track.scatter_m == pytest.approx(0.01, rel=0.3)
    assert track.declared_sigma_m == pytest.approx(0.012)
    assert all(p.used for p in track.points)


def test_without_sigma_the_declared_target_precision_is_used(tmp_path):
    yaml, _ = _write(tmp_path, sigma=False, yaml_extra="precision: {target_mm: 8}\n")
    track = build_track(load_survey(str(yaml)))
    assert track.declared_sigma_m == pytest.approx(0.008)


def _error(yaml) -> str:
    with pytest.raises(InputError) as err:
        build_track(load_survey(str(yaml)))
    return str(err.value)


@pytest.mark.parametrize(
    ("old", "new", "expect"),
    [
        ("P010,", "P010,nan#", ":12: field e: 'nan"),
        (",0.012\nP011", ",-0.5\nP011", ":12: field sigma_h: a standard deviation"),
        ("P020,", "P020,1e99#", ":22: field e: "),
        ("P030,", "P030,12,5#", ":32: 5 fields where the header has 5"),
        ("id,e,n,h,sigma_h", "id,e,n,height,sigma_h", ":1: missing column(s) h"),
        ("P040,", "P005,", ":42: field id: point id 'P005' already given on line 7"),
    ],
)
def test_bad_coordinates_are_located(tmp_path, old, new, expect):
    yaml, _ = _write(tmp_path)
    csv_path = tmp_path / "pts.csv"
    text = csv_path.read_text()
    if "#" in new:  # replace the first number after the id
        pid, val = new.split(",", 1)
        val = val.rstrip("#")
        start = text.index(old)
        end = text.index(",", start + len(old))
        text = text[:start] + f"{pid},{val}" + text[end:]
    else:
        text = text.replace(old, new, 1)
    csv_path.write_text(text)
    msg = _error(yaml)
    if "fields where" in expect:
        assert msg.startswith(f"{csv_path}:32: 6 fields where the header has 5")
    else:
        assert msg.startswith(f"{csv_path}{expect}"), msg


def test_decimal_comma_with_comma_separator_is_explained(tmp_path):
    yaml, _ = _write(tmp_path)
    csv_path = tmp_path / "pts.csv"
    csv_path.write_text("id,e,n,h\nA,1\n")
    msg = _error(yaml)
    assert msg.startswith(f"{csv_path}:2: 2 fields")
    csv_path.write_text("id;e;n;h\nA;1.5;2;1650,0\nB;x;2;3\n")
    msg = _error(yaml)
    assert msg.startswith(f"{csv_path}:3: field e: 'x' is not a number")
    csv_path.write_text('id,e,n,h\nA,"1,5",2,1650\n')
    assert "a decimal comma needs ';'" in _error(yaml)


def test_a_device_is_not_read(tmp_path):
    yaml = tmp_path / "dev.yaml"
    yaml.write_text("points: /dev/zero\nphotocells: []\n")
    assert "/dev/zero: not a regular file" in _error(yaml)


@pytest.mark.parametrize("kind", ["missing", "folder", "latin1", "empty", "height"])
def test_unreadable_coordinate_files(tmp_path, kind):
    yaml, _ = _write(tmp_path)
    csv_path = tmp_path / "pts.csv"
    if kind == "missing":
        csv_path.unlink()
        assert "coordinate file 'pts.csv' not found" in _error(yaml)
        return
    if kind == "folder":
        csv_path.unlink()
        csv_path.mkdir()
        assert "is a folder" in _error(yaml)
        return
    if kind == "latin1":
        csv_path.write_bytes("id,e,n,h\nHöhe,1,2,3\n".encode("latin-1"))
        assert "not a UTF-8 text file" in _error(yaml)
        return
    if kind == "empty":
        csv_path.write_text("\n\n")
        assert "empty coordinate file" in _error(yaml)
        return
    csv_path.write_text("id,e,n,h\nA,1,2,12000\n")
    assert _error(yaml).startswith(f"{csv_path}:2: field h: height 12000.0 m")


def test_coordinates_beside_observations(tmp_path):
    """Profile from the total station, photocell posts from a GNSS rover's list."""
    from conftest import DEMO_SURVEY

    from station.survey.load import load_survey as load

    demo = load(str(DEMO_SURVEY))
    posts = [p for pid, p in demo.points.items() if pid.startswith("PC")]
    lines = ["id,e,n,h"] + [f"G{p.point},{p.e:.4f},{p.n:.4f},{p.h:.4f}" for p in posts]
    (tmp_path / "posts.csv").write_text("\n".join(lines) + "\n")
    text = DEMO_SURVEY.read_text().replace(
        "observations: demo_run.gsi",
        f"observations: {DEMO_SURVEY.parent / 'demo_run.gsi'}\npoints: posts.csv",
    )
    text = text.replace("[PC", "[GPC").replace(", PC", ", GPC")
    (tmp_path / "mixed.yaml").write_text(text)
    track = build_track(load(str(tmp_path / "mixed.yaml")))
    ref = build_track(demo)
    assert [pc.x for pc in track.photocells] == pytest.approx([pc.x for pc in ref.photocells])
