"""Property: whatever a user writes in the [capture] table (and its [[capture.regions]]), in a trainer's
cameras.json or in a sweep's cache files, the reader either accepts it and the result is sound, or raises the
package's error with a one-line message — never another exception, never a hang. Values are drawn from every
type (ints, floats with NaN, inf, negative and huge values, strings, lists, tables) and keys are dropped.

"Sound" is checked against the rules the issue states, written out here (not imported from the validator):
a positive size and cell count, a percentile in [0, 100], a non-negative load speed and fill closing that
allocates no more than a small grid, a positive fill budget, a positive scale, a proper rotation; a camera with
finite values, positive focal lengths and image size and a proper rotation; a cached row the sweep's tables
can print."""

from __future__ import annotations

import dataclasses
import json
import math
import typing
from datetime import timedelta

import pytest
from fuzzutil import Tally, fuzz_settings
from hypothesis import given, settings
from hypothesis import strategies as st

from fracture_gs.capture.fit import read_cameras
from fracture_gs.config import CaptureConfig, MaterialRegion
from fracture_gs.errors import ConfigError, FractureGSError, OutputError, SceneError
from fracture_gs.io.config import config_from_dict
from fracture_gs.io.config.dump import config_to_dict
from fracture_gs.sweep import cache, expansion, load_spec
from fracture_gs.sweep.driver import base_row
from fracture_gs.sweep.report import accuracy_results, csv_text, sweep_table

HINTS = typing.get_type_hints(CaptureConfig)
KEYS = [f.name for f in dataclasses.fields(CaptureConfig)]
REGION_KEYS = [f.name for f in dataclasses.fields(MaterialRegion)]
FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 1e300, 1e9, 0.5, 50.0, 100.0, 1e6, math.nan, math.inf]),
)
INTS = st.one_of(st.integers(-(2**63), 2**63 - 1), st.sampled_from([0, -1, 1, 4, 8, 9, 1000, 10**9]))
TEXT = st.text(st.characters(exclude_categories=["Cs"]), max_size=10)
SCALARS = st.one_of(INTS, FLOATS, st.booleans(), TEXT)
VALUES = st.one_of(
    SCALARS,
    st.lists(st.one_of(FLOATS, st.integers(-3, 3)), max_size=4),
    st.lists(st.lists(FLOATS, min_size=3, max_size=3), min_size=3, max_size=3),
    st.dictionaries(TEXT, SCALARS, max_size=2),
)


def bounded(examples: int) -> settings:
    """The suite's settings with a per-example deadline: a reader that hangs (a 32 GB closing, a million-cell
    expansion) fails the test instead of stalling it."""
    return settings(fuzz_settings(examples), deadline=timedelta(seconds=20))


def typed(tp):
    """A value of the key's declared type, often near or past the edges of its range."""
    if typing.get_origin(tp) is typing.Literal:
        return st.sampled_from(typing.get_args(tp))
    if typing.get_origin(tp) is typing.Union:
        tp = next(a for a in typing.get_args(tp) if a is not type(None))
    if tp is bool:
        return st.booleans()
    if tp is int:
        return st.one_of(st.integers(-3, 1100), st.sampled_from([0, 4, 8, 9, 1024, 1025]))
    if tp is float:
        return st.one_of(st.floats(-2.0, 200.0), st.sampled_from([0.0, 1e-3, 49.9, 50.0, 100.0, 1e9]))
    if tp is str:
        return TEXT
    if typing.get_origin(tp) is tuple and typing.get_origin(typing.get_args(tp)[0]) is tuple:  # a 3×3 matrix
        proper = st.sampled_from(
            [((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)), ((1.0, 0, 0), (0, 1.0, 0), (0, 0, 1.0))]
        )
        return st.one_of(
            proper, st.lists(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), min_size=3, max_size=3)
        )
    if typing.get_origin(tp) is tuple:
        return st.lists(st.floats(-200.0, 200.0), min_size=3, max_size=3)
    return VALUES


@st.composite
def region(draw):
    table = {}
    for key in draw(st.lists(st.sampled_from(REGION_KEYS), unique=True, max_size=3)):
        tp = typing.get_type_hints(MaterialRegion)[key]
        table[key] = draw(typed(tp) if draw(st.booleans()) else VALUES)
    return table if draw(st.integers(0, 9)) else draw(SCALARS)


@st.composite
def capture_table(draw):
    table = {}
    for key in draw(st.lists(st.sampled_from(KEYS), unique=True, max_size=6)):
        if key == "regions":
            table[key] = draw(st.lists(region(), max_size=2)) if draw(st.integers(0, 4)) else draw(VALUES)
        else:
            table[key] = draw(typed(HINTS[key]) if draw(st.integers(0, 3)) else VALUES)
    return table


def is_proper_rotation(R) -> bool:
    cols = [[R[i][j] for i in range(3)] for j in range(3)]
    gram = max(abs(sum(a * b for a, b in zip(cols[i], cols[j])) - (i == j)) for i in range(3) for j in range(3))
    det = (
        R[0][0] * (R[1][1] * R[2][2] - R[1][2] * R[2][1])
        - R[0][1] * (R[1][0] * R[2][2] - R[1][2] * R[2][0])
        + R[0][2] * (R[1][0] * R[2][1] - R[1][1] * R[2][0])
    )
    return gram < 1e-2 and det > 0


def check_capture(cap: CaptureConfig) -> None:
    """The issue's rules for an accepted [capture] table."""
    floats = [v for v in (cap.size, cap.percentile, cap.load_speed, cap.min_opacity, cap.outlier_std) if v is not None]
    assert all(math.isfinite(v) for v in floats)
    assert 0 < cap.size <= 1e3, "a positive, sane object size"
    assert cap.cells_across is None or 0 < cap.cells_across <= 4096, "cells across: no division by zero"
    assert 0 <= cap.percentile <= 100 and cap.load_speed >= 0 and cap.load_speed < 1e4
    k = 2 * cap.fill_closing + 1
    assert 0 <= cap.fill_closing and (256 + 2 * k) ** 3 * 4 < 2**31, "the closing's padded grid fits in 2 GB"
    assert cap.max_particles is None or cap.max_particles > 0
    assert cap.scale is None or (math.isfinite(cap.scale) and cap.scale > 0)
    assert cap.rotation is None or is_proper_rotation(cap.rotation)
    assert cap.view >= 0 and 0 <= cap.min_opacity <= 1 and cap.outlier_neighbours >= 0
    for r in cap.regions:
        assert all(lo < hi for lo, hi in zip(r.lower, r.upper)) and r.material != "config"
    # keys the rest of the table would make do nothing (issue 34, round three)
    assert cap.view == 0 or cap.camera != "auto", "a trainer view without the trainer camera"
    assert cap.load_speed == 0 or cap.load != "none", "a load speed without a load"
    assert cap.ground_level is None or cap.ground != "none", "a ground level with the ground turned off"
    # ... and round four
    assert cap.outlier_neighbours != 0 or cap.outlier_std == 3.0, "an outlier cut with the outlier removal off"
    assert cap.roi not in ("sphere", "all") or cap.percentile == 1.0, "a percentile beside a ROI it does not bound"
    if cap.rotation is not None and cap.up != "auto":
        axis = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "+z": (0, 0, 1), "-z": (0, 0, -1)}
        row = cap.rotation[2]  # the scene axis the rotation takes to the simulation's up, +z
        cos = sum(a * b for a, b in zip(axis[cap.up], row)) / math.sqrt(sum(v * v for v in row))
        assert cos > 0.99, "an up axis the rotation contradicts"


DEFAULT_CAPTURE = dataclasses.asdict(CaptureConfig())
"""What [capture] holds when no key is written: the only table a built-in scene or `fit = false` may have (round
four: every other key there would do nothing; `fit` itself is the exception of the second)."""


def check_scene_kind(cfg, kind: str) -> None:
    """Round four's rules on the scene around the table: nothing but defaults on a built-in scene or beside
    fit = false, and no interior-fill budget without a fill."""
    # capture.panel: runs wrote "config" on every scene, and such a config.toml loads again
    skip = ("panel",) if kind == "bread" else ("panel", "fit")
    held = {k: v for k, v in dataclasses.asdict(cfg.capture).items() if k not in skip}
    if kind == "bread" or not cfg.capture.fit:
        assert held == {k: v for k, v in DEFAULT_CAPTURE.items() if k in held}, "a [capture] key that does nothing"
    assert cfg.fill_interior or cfg.capture.max_particles is None, "a fill budget without a fill"


def one_line(err: BaseException) -> None:
    assert str(err).strip() and "\n" not in str(err), repr(err)


@pytest.mark.usefixtures("one_thread")
def test_fuzz_capture_keys(capsys):
    tally = Tally("capture keys")

    @bounded(300)
    @given(capture_table(), st.sampled_from(["capture"] * 4 + ["bread"]), st.integers(0, 5))
    def documents(table, kind, fill):
        doc = {"extends": kind, "capture": table} if kind == "bread" else {"extends": kind, "scene": "scene.ply"}
        doc["capture"] = table
        if not fill:
            doc["fill_interior"] = False
        try:
            cfg = config_from_dict(doc, "fuzz.toml")
        except ConfigError as err:
            one_line(err)
            tally.add("[capture] table", "our error")
            return
        except Exception:
            tally.add("[capture] table", "traceback")
            raise
        check_capture(cfg.capture)
        check_scene_kind(cfg, kind)
        again = config_from_dict(config_to_dict(cfg), "round trip")  # what init writes loads back
        assert again.capture == cfg.capture
        tally.add("[capture] table", "clean load")

    documents()
    tally.report(capsys)
    c = tally.counts["[capture] table"]
    assert c["traceback"] == 0 and c["clean load"] > 15 and c["our error"] > 100


# ---------------------------------------------------------------- cameras.json

CAMERA_KEYS = ("position", "rotation", "fx", "fy", "width", "height", "img_name", "id")
GOOD = {
    "id": 0,
    "img_name": "00000",
    "width": 640,
    "height": 480,
    "position": [1.0, 2.0, 3.0],
    "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    "fx": 500.0,
    "fy": 500.0,
}


@st.composite
def camera(draw):
    cam = dict(GOOD)
    for key in draw(st.lists(st.sampled_from(CAMERA_KEYS), unique=True, max_size=3)):
        if draw(st.integers(0, 4)) == 0:
            cam.pop(key)
        elif key == "rotation" and draw(st.booleans()):
            cam[key] = draw(st.lists(st.lists(FLOATS, min_size=3, max_size=3), min_size=3, max_size=3))
        elif key in ("fx", "fy", "width", "height") and draw(st.booleans()):
            cam[key] = draw(st.one_of(FLOATS, st.integers(-2, 10**6), st.sampled_from([10**400, 1e-300, 1e300, 1])))
        elif key == "position" and draw(st.booleans()):
            cam[key] = [draw(st.one_of(FLOATS, st.sampled_from([10**400, 1e300, -1e12]))), 0.0, 0.0]
        else:
            cam[key] = draw(VALUES)
    return cam


def check_camera(c) -> None:
    """The issue's rules for an accepted view: finite, positive focal lengths and image size, a rotation."""
    assert math.isfinite(c.fx) and c.fx > 0 and math.isfinite(c.fy) and c.fy > 0
    assert c.width >= 1 and c.height >= 1
    assert bool(c.position.isfinite().all()) and bool(c.rotation.isfinite().all())
    assert float(c.position.abs().max()) <= 1e9, "a camera position the fit can still hold in float32"
    assert is_proper_rotation(c.rotation.tolist())


def test_fuzz_cameras_json(tmp_path, capsys):
    tally = Tally("cameras.json")
    path = tmp_path / "cameras.json"

    @bounded(250)
    @given(st.integers(0, 3).flatmap(lambda k: VALUES if k == 0 else st.lists(camera(), min_size=1, max_size=3)))
    def files(data):
        path.write_text(json.dumps(data))
        kind = "views" if isinstance(data, list) and data and all(isinstance(c, dict) for c in data) else "other"
        try:
            cams = read_cameras(path)
        except SceneError as err:
            one_line(err)
            assert str(err).startswith(f"{path}: ")
            tally.add(kind, "our error")
            return
        except Exception:
            tally.add(kind, "traceback")
            raise
        for c in cams:
            check_camera(c)
        tally.add(kind, "clean load")

    files()
    tally.report(capsys)
    assert tally.total("traceback") == 0 and tally.counts["views"]["clean load"] > 0
    assert tally.counts["views"]["our error"] > 80


# ---------------------------------------------------------------- sweep cache rows

ROW_KEYS = (
    "status",
    "message",
    "dt",
    "particles",
    "substeps",
    "wall_s",
    "error",
    "unit",
    "cell_s",
    "latch_frame",
    "opening",
    "fragments",
    "penetration_max",
    "device",
    "extra",
    "traceback",
)
GOOD_ROW = {
    "status": "ok",
    "message": "",
    "dt": 1e-4,
    "particles": 100,
    "substeps": 10,
    "wall_s": 0.1,
    "error": 0.01,
    "unit": "rel",
    "cell_s": 0.2,
    "device": "cpu",
}


@st.composite
def cache_row(draw):
    row = dict(GOOD_ROW)
    for key in draw(st.lists(st.sampled_from(ROW_KEYS), unique=True, max_size=3)):
        if draw(st.integers(0, 4)) == 0:
            row.pop(key, None)
        else:
            row[key] = draw(st.one_of(VALUES, st.sampled_from(["ok", "failed", "missing", None, 10**400, -1, -0.5, 0])))
    return row if draw(st.integers(0, 9)) else draw(VALUES)


def check_row_values(r: dict) -> None:
    """What a run writes (issue 34, round three): counts and times are not negative, a step is positive, every
    number is a float the tables can format, and a finished accuracy cell simulated something."""
    for key, v in r.items():
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            assert math.isfinite(float(v)), key
    for key in ("particles", "substeps", "latch_frame", "fragments"):
        assert r.get(key) is None or r[key] >= 0, key
    for key in ("wall_s", "cell_s", "error"):
        assert r.get(key) is None or r[key] >= 0, key
    assert r.get("dt") is None or r["dt"] > 0
    if r["status"] == "ok":
        assert r["particles"] >= 1 and r["substeps"] >= 1


SPEC = '[sweep]\nwarmup = false\n[[accuracy]]\ncase = ["bar"]\ncells = [16]\ncfl = 0.4\n'


def test_fuzz_sweep_cache_rows(tmp_path, capsys):
    tally = Tally("sweep cache")
    spec_path = tmp_path / "spec.toml"
    spec_path.write_text(SPEC)
    spec = load_spec(spec_path)
    cell = expansion.expand(spec)[0]
    path = cache.cache_path(tmp_path, cell.id)
    path.parent.mkdir()

    @bounded(250)
    @given(cache_row())
    def rows(row):
        path.write_text(json.dumps({"id": cell.id, "params": cell.params, "row": row}))
        try:
            found = cache.scan(tmp_path, [cell], "cpu")
        except OutputError as err:
            one_line(err)
            assert str(err).startswith(f"{path}: ") or str(err).startswith(f"{path} ")
            tally.add("row", "our error")
            return
        except FractureGSError:
            raise
        except Exception:
            tally.add("row", "traceback")
            raise
        for r in found.values():  # an accepted row goes through what rank 0 does with it: the tables
            check_row_values(r)
            merged = {**r, **base_row(cell)}
            table = sweep_table("fuzz", [merged], "caption", "command")
            table.markdown(), table.latex(), csv_text([merged]), accuracy_results([merged])
            json.dumps(merged, allow_nan=False)
        tally.add("row", "clean load")

    rows()
    tally.report(capsys)
    assert tally.total("traceback") == 0 and tally.counts["row"]["clean load"] > 0
    assert tally.counts["row"]["our error"] > 50
