"""Bad input, round two (issue 34, item 5) for the capture keys, cameras.json, the sweep cache and sweep
specs that multiply out to millions of cells: every refused value is a `fracture_gs.errors` exception whose
one-line message names the key (and, for files, the file), or exit code 2 from the CLI with no traceback;
the fit keys are honoured alone; a huge spec is refused at once and a large one lists its first cells at
once."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest
import torch
from trainer_ply import write_cameras, write_trainer_ply

from fracture_gs.capture.fit import read_cameras
from fracture_gs.capture.scene import resolve
from fracture_gs.cli import main
from fracture_gs.errors import ConfigError, OutputError, SceneError
from fracture_gs.io.config import config_from_dict
from fracture_gs.sweep import cache, driver, expansion, load_spec
from fracture_gs.sweep.cells import Outcome

pytestmark = pytest.mark.usefixtures("one_thread")


def capture_doc(scene: str = "scene.ply", **capture) -> dict:
    return {"extends": "capture", "scene": scene, "capture": capture}


def one_line(err: BaseException) -> str:
    msg = str(err)
    assert msg.strip() and "\n" not in msg and msg.rstrip().endswith((".", "?")), msg
    return msg


# ---------------------------------------------------------------- [capture] keys

ROT90 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
CAPTURE_PROBES = [
    ({"size": 0.0}, "capture.size"),
    ({"size": -0.5}, "capture.size"),
    ({"size": 1e9}, "capture.size"),
    ({"cells_across": 0}, "capture.cells_across"),
    ({"fill_closing": 1000}, "capture.fill_closing"),
    ({"fill_closing": -1}, "capture.fill_closing"),
    ({"percentile": -1.0}, "capture.percentile"),
    ({"percentile": 101.0}, "capture.percentile"),
    ({"percentile": 50.0}, "capture.percentile"),
    ({"load_speed": -1.0}, "capture.load_speed"),
    ({"load_speed": 1e6}, "capture.load_speed"),
    ({"max_particles": 0}, "capture.max_particles"),
    ({"max_particles": -5}, "capture.max_particles"),
    ({"min_opacity": -0.1}, "capture.min_opacity"),
    ({"min_opacity": 1.5}, "capture.min_opacity"),
    ({"outlier_neighbours": -1}, "capture.outlier_neighbours"),
    ({"outlier_neighbours": 10**6}, "capture.outlier_neighbours"),
    ({"outlier_std": 0.0}, "capture.outlier_std"),
    ({"fill_threshold": 0.0}, "capture.fill_threshold"),
    ({"view": -1}, "capture.view"),
    ({"cameras_json": " "}, "capture.cameras_json"),
    ({"roi": "box"}, "capture.roi_lower"),
    ({"roi": "box", "roi_lower": [1.0, 0, 0], "roi_upper": [0.0, 1, 1]}, "capture.roi_lower"),
    ({"roi": "sphere", "roi_center": [0.0, 0, 0]}, "capture.roi_radius"),
    ({"roi": "sphere", "roi_center": [0.0, 0, 0], "roi_radius": -1.0}, "capture.roi_radius"),
    ({"roi_radius": 1.0}, "capture.roi_radius"),
    ({"roi": "sphere", "roi_center": [0.0, 0, 0], "roi_radius": 1.0, "roi_upper": [1.0, 1, 1]}, "capture.roi_upper"),
    ({"scale": 0.0}, "capture.scale"),
    ({"scale": -2.0}, "capture.scale"),
    ({"rotation": [[1.0, 0, 0], [0.0, 1, 0], [0.0, 0, 0]]}, "capture.rotation"),
    ({"rotation": [[2.0, 0, 0], [0.0, 1, 0], [0.0, 0, 1]]}, "capture.rotation"),
    ({"rotation": [[1.0, 0, 0], [0.5, 1, 0], [0.0, 0, 1]]}, "capture.rotation"),
    ({"rotation": [[1.0, 0, 0], [0.0, 1, 0], [0.0, 0, -1]]}, "capture.rotation"),
    ({"offset": [1e9, 0.0, 0.0]}, "capture.offset"),
    ({"fit": False, "rotation": ROT90}, "capture.rotation"),
    ({"regions": [{"lower": [1.0, 0, 0], "upper": [0.0, 1, 1]}]}, "capture.regions[0]"),
    ({"regions": [{"lower": [0.0, 0, 0], "upper": [1.0, 1, 1], "material": "config"}]}, "capture.regions[0].material"),
]


@pytest.mark.parametrize("values, key", CAPTURE_PROBES, ids=[f"{k}={v}" for v, k in CAPTURE_PROBES])
def test_capture_key_out_of_range_is_a_config_error_naming_it(values, key):
    """Rule: every [capture] key is range-checked where the config is loaded (a value that divides by zero,
    allocates gigabytes, is ignored or makes no geometric sense), in one sentence naming the key."""
    with pytest.raises(ConfigError) as info:
        config_from_dict(capture_doc(**values), "probe.toml")
    msg = one_line(info.value)
    assert msg.startswith("probe.toml: ") and key in msg, msg


def test_capture_values_at_the_edges_of_their_ranges_load():
    """Rule: the bounds are not too tight: the values a user means (a closing of 8, a proper rotation given
    to four digits, a 1 mm or 100 m object, the 0th percentile, a load of 100 m/s) load."""
    c = 2**-0.5
    cfg = config_from_dict(
        capture_doc(
            fill_closing=8,
            size=100.0,
            percentile=0.0,
            load_speed=100.0,
            rotation=[[0.7071, -0.7071, 0.0], [0.7071, 0.7071, 0.0], [0.0, 0.0, 1.0]],
            scale=3.0,
            offset=[-100.0, 0.0, 100.0],
            outlier_neighbours=0,
            min_opacity=0.0,
        )
    )
    assert cfg.capture.fill_closing == 8 and cfg.capture.size == 100.0 and cfg.capture.rotation[0][0] == 0.7071
    assert abs(cfg.capture.rotation[0][0] - c) < 1e-3
    assert config_from_dict(capture_doc(size=1e-3)).capture.size == 1e-3


def test_resolve_checks_a_config_built_in_python():
    """Rule: the Python API refuses what the loader refuses: a config edited after loading (size = 0, the
    divide-by-zero of the issue) is refused by `resolve` before the file is even read."""
    cfg = config_from_dict(capture_doc(scene="no_such_dir/scene.ply"))
    cfg.capture.size = 0.0
    with pytest.raises(ConfigError) as info:
        resolve(cfg)
    assert "capture.size" in one_line(info.value)


@pytest.fixture(scope="module")
def small_ply(tmp_path_factory):
    ply, _ = write_trainer_ply(tmp_path_factory.mktemp("bad_input_capture"), n=1500)
    return ply


def quick(ply, **capture) -> dict:
    return capture_doc(str(ply), cells_across=8, max_particles=1500, **capture)


@pytest.mark.slow
def test_scale_rotation_and_offset_are_each_honoured_alone(small_ply):
    """Rule: capture.scale, rotation or offset given alone is applied (the others found around it), not
    silently dropped: the resolved transform holds the given value, and a given scale sets the object's
    size (its longest fitted side = scale × its longest side in scene units)."""
    auto = resolve(config_from_dict(quick(small_ply)))
    s = auto.transform.scale
    scaled = resolve(config_from_dict(quick(small_ply, scale=0.5 * s)))
    assert scaled.transform.scale == 0.5 * s
    assert scaled.cfg.capture.size == pytest.approx(0.5 * auto.cfg.capture.size, rel=1e-9), "size follows scale"
    assert torch.equal(scaled.transform.rotation, auto.transform.rotation), "the rotation stays automatic"
    turned = [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]  # scene -y onto +z, then a quarter turn
    rotated = resolve(config_from_dict(quick(small_ply, rotation=turned)))
    assert rotated.transform.rotation.tolist() == turned and rotated.cfg.capture.rotation == tuple(map(tuple, turned))
    moved = resolve(config_from_dict(quick(small_ply, offset=[1.0, 2.0, 3.0])))
    assert moved.transform.offset.tolist() == [1.0, 2.0, 3.0]
    assert moved.transform.scale == s, "the scale stays automatic"
    shift = torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64) - auto.transform.offset
    lo = [g.means[~g.interior].double().min(0).values for g in (auto.gaussians, moved.gaussians)]
    assert torch.allclose(lo[1] - lo[0], shift, atol=1e-4), "the object sits where the given offset puts it"


@pytest.mark.slow
def test_a_scale_that_makes_an_absurd_object_is_refused(small_ply):
    """Rule: a scale that makes the object's longest side leave capture.size's range is a SceneError naming
    capture.scale (and the scale that would give capture.size)."""
    with pytest.raises(SceneError) as info:
        resolve(config_from_dict(quick(small_ply, scale=1e6)))
    assert "capture.scale" in one_line(info.value) and str(small_ply) in str(info.value)


# ---------------------------------------------------------------- cameras.json


def camera_file(tmp_path, mutate) -> Path:
    path = tmp_path / "cameras.json"
    write_cameras(path, views=3)
    data = json.loads(path.read_text())
    mutate(data)
    path.write_text(json.dumps(data))
    return path


def _set(i, key, value):
    def mutate(data):
        data[i][key] = value

    return mutate


def _pop(i, key):
    return lambda data: data[i].pop(key)


def _rot(i, r, c, value):
    def mutate(data):
        data[i]["rotation"][r][c] = value

    return mutate


CAMERA_PROBES = [
    (_set(0, "fx", 0.0), 0, "fx"),
    (_set(1, "fy", -500.0), 1, "fy"),
    (_set(2, "width", 0), 2, "width"),
    (_set(0, "height", -480), 0, "height"),
    (_set(0, "width", 640.5), 0, "width"),
    (_set(1, "fx", math.nan), 1, "fx"),
    (_set(1, "fy", math.inf), 1, "fy"),
    (_rot(2, 0, 0, math.nan), 2, "rotation"),
    (_rot(0, 1, 1, 2.0), 0, "rotation"),
    (_set(1, "rotation", [[1.0, 0, 0], [0.0, 1, 0], [0.0, 0, -1]]), 1, "rotation"),
    (_set(1, "rotation", [[1.0, 0, 0], [0.0, 1, 0]]), 1, "rotation"),
    (_set(0, "position", [1.0, math.nan, 0.0]), 0, "position"),
    (_set(0, "position", "origin"), 0, "position"),
    (_set(2, "fx", "500"), 2, "fx"),
    (_set(2, "width", True), 2, "width"),
    *[(_pop(1, key), 1, key) for key in ("position", "rotation", "fx", "fy", "width", "height")],
]


@pytest.mark.parametrize(
    "mutate, view, key", CAMERA_PROBES, ids=[f"camera{v}-{k}-{i}" for i, (_, v, k) in enumerate(CAMERA_PROBES)]
)
def test_bad_camera_entry_names_the_file_the_camera_and_the_key(tmp_path, mutate, view, key):
    """Rule: a cameras.json view with a zero or negative focal length or image size, NaN or inf anywhere
    (rotations included), a matrix that is not a proper rotation, a missing key or a value of the wrong type
    is a SceneError of one sentence naming the file, the camera and the key (it would divide by zero or be
    averaged into the up axis unnoticed)."""
    path = camera_file(tmp_path, mutate)
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    msg = one_line(info.value)
    assert msg.startswith(f"{path}: camera {view} ") and f": {key} " in msg, msg


@pytest.mark.parametrize("text", ["[]", '{"fx": 1}', "[1, 2]", "not json", "[null]"])
def test_a_cameras_file_that_is_no_list_of_views_is_one_sentence(tmp_path, text):
    """Rule: a cameras.json that is not a non-empty list of view objects is a SceneError naming the file."""
    path = tmp_path / "cameras.json"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    assert one_line(info.value).startswith(f"{path}: ")


def test_the_trainer_cameras_read_back_unchanged(tmp_path):
    """Rule: the checks pass a trainer's real views (proper rotations written to float precision)."""
    path = camera_file(tmp_path, lambda data: None)
    cams = read_cameras(path)
    data = json.loads(path.read_text())
    assert [c.fx for c in cams] == [500.0] * 3 and cams[1].rotation.tolist() == data[1]["rotation"]


# ---------------------------------------------------------------- the sweep cache

SPEC = '[sweep]\nwarmup = false\n[[accuracy]]\ncase = ["bar"]\ncells = [16, 24]\ncfl = 0.4\n'


def fake_cell(cell, device, out_dir=None):
    return Outcome({"dt": 1e-4, "particles": 100, "substeps": 10, "wall_s": 0.1, "error": 0.01, "unit": "rel"})


@pytest.fixture(scope="module")
def cached_template(tmp_path_factory):
    """A two-cell accuracy sweep run once with a stand-in for the solver: (spec, out folder)."""
    tmp = tmp_path_factory.mktemp("cached_sweep")
    spec = tmp / "spec.toml"
    spec.write_text(SPEC)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(driver, "run_cell", fake_cell)
        assert main(["sweep", str(spec), "--device", "cpu", "--out", str(tmp / "out")]) == 0
    return spec, tmp / "out"


@pytest.fixture
def cached(cached_template, tmp_path, monkeypatch):
    """A copy of the cached sweep: (spec, out folder, the first cell's cache file); the solver stays stubbed."""
    monkeypatch.setattr(driver, "run_cell", fake_cell)
    spec, template = cached_template
    out = tmp_path / "out"
    shutil.copytree(template, out)
    first = cache.cache_path(out, expansion.expand(load_spec(spec))[0].id)
    assert first.is_file()
    return spec, out, first


def sweep(spec, out, capsys, *extra) -> tuple[int, str, str]:
    """(exit code, stdout, stderr) of `fracture-gs sweep` run in this process; never a traceback."""
    code = main(["sweep", str(spec), "--device", "cpu", "--out", str(out), *extra])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    return code, captured.out, captured.err


def _row(key, value):
    def edit(path: Path):
        payload = json.loads(path.read_text())
        payload["row"][key] = value
        path.write_text(json.dumps(payload))

    return edit


def _folder(path: Path):
    path.unlink()
    path.mkdir()


def _cells_file(path: Path):
    shutil.rmtree(path.parent)
    path.parent.write_text("not a folder")


CACHE_PROBES = [
    (_folder, "file", "is a folder, not a sweep cache file"),
    (_cells_file, "folder", "is a file, not the sweep's cache folder"),
    (_row("particles", "abc"), "file", "particles is the string 'abc'"),
    (_row("wall_s", "x"), "file", "wall_s is the string 'x'"),
    (_row("error", math.nan), "file", "error is nan"),
    (_row("dt", math.inf), "file", "dt is inf"),
    (_row("status", 5), "file", "status is the number 5"),
    (_row("substeps", 2.5), "file", "substeps is the number 2.5"),
    (_row("message", ["a"]), "file", "message is a list"),
    (lambda p: p.write_text("garbage"), "file", "not JSON"),
    (lambda p: p.write_text('{"id": 3}'), "file", "not a sweep cache file"),
]


@pytest.mark.parametrize("corrupt, where, needle", CACHE_PROBES, ids=[n for *_, n in CACHE_PROBES])
def test_a_damaged_cache_is_one_line_naming_the_file_and_the_fix(cached, capsys, corrupt, where, needle):
    """Rule: a cache file replaced by a folder, `cells/` being a file, or a cached row with a wrong type or
    NaN ends as exit 2 and one line naming the path, what is wrong and the fix (delete it, --fresh or
    another --out), never a traceback or a number misread into the tables; --list says the same."""
    spec, out, first = cached
    corrupt(first)
    code, _, err = sweep(spec, out, capsys)
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("fracture-gs: error: "), err
    path = str(first) if where == "file" else str(first.parent)
    assert f"error: {path}" in lines[0] and needle in lines[0], lines[0]
    assert "delete" in lines[0] or "--out" in lines[0]
    code, _, err = sweep(spec, out, capsys, "--list")
    assert code == 2 and needle in err


def test_fresh_rebuilds_a_damaged_cache_file(cached, capsys):
    """Rule: the fix the message names works: --fresh runs the cell again over an unreadable cache file."""
    spec, out, first = cached
    first.write_text("garbage")
    assert sweep(spec, out, capsys, "--fresh")[0] == 0
    assert json.loads(first.read_text())["row"]["status"] == "ok"


def test_non_finite_metrics_are_written_as_null_so_the_cache_reads_back(tmp_path):
    """Rule: the writer never leaves a row its reader refuses: a NaN metric is stored as null."""
    cell = expansion.expand(load_spec(_spec(tmp_path)))[0]
    cache.store(tmp_path, cell, {"status": "failed", "message": "diverged", "opening": math.nan, "wall_s": 1.0})
    assert cache.load(tmp_path, cell)["opening"] is None


def test_the_python_api_raises_output_error_for_a_damaged_row(tmp_path):
    """Rule: `cache.load` (the reader every caller goes through) raises the package's OutputError naming the
    file and the key, for a row with a string where the table prints an integer."""
    cell = expansion.expand(load_spec(_spec(tmp_path)))[0]
    cache.store(tmp_path, cell, {"status": "ok", "particles": 100})
    path = cache.cache_path(tmp_path, cell.id)
    payload = json.loads(path.read_text())
    payload["row"]["particles"] = "100"
    path.write_text(json.dumps(payload))
    with pytest.raises(OutputError) as info:
        cache.load(tmp_path, cell)
    assert one_line(info.value).startswith(f"{path}: ") and "particles" in str(info.value)


def _spec(tmp_path, text=SPEC) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


def test_an_unexpected_value_error_is_not_disguised_as_a_user_error(cached, monkeypatch, capsys):
    """Rule: only the package's own errors print as one-line user errors (exit 2); a bare ValueError inside the
    sweep (a bug, e.g. int('abc') in a table) says it is a bug in fracture-gs, exit 1, not a line naming no file."""
    spec, out, _ = cached

    def broken(*args, **kwargs):
        raise ValueError("invalid literal for int() with base 10: 'abc'")

    monkeypatch.setattr(driver, "write_outputs", broken)
    assert main(["sweep", str(spec), "--device", "cpu", "--out", str(out)]) == 1
    assert "internal error: ValueError" in capsys.readouterr().err


# ---------------------------------------------------------------- sweep size

HUGE = '[sweep]\nwarmup = false\n[[accuracy]]\ncase = ["bar", "spin", "recontact"]\ncells = [{}]\ncfl = [{}]\n'.format(
    ", ".join(str(4 * i) for i in range(1, 1001)), ", ".join(f"{0.001 * i:.3f}" for i in range(1, 1001))
)  # 3 × 1000 × 1000 = 3,000,000 cells


def test_a_spec_of_millions_of_cells_is_refused_before_any_cell_is_made(tmp_path, monkeypatch):
    """Rule: a spec over the cap (default 10,000) is one sentence giving the count and how to raise the cap,
    found by multiplying the list lengths, not by making the cells (making one here would fail the test)."""

    def no_cells(*args, **kwargs):
        raise AssertionError("a cell was made")

    monkeypatch.setattr(expansion, "accuracy_cost", no_cells)
    with pytest.raises(ConfigError) as info:
        expansion.expand(load_spec(_spec(tmp_path, HUGE)))
    msg = one_line(info.value)
    assert "sweep.max_cells" in msg and "3,000,000" in msg and "--max-cells 3000000" in msg and "10,000" in msg


def test_a_huge_spec_through_the_cli_is_exit_2_even_with_list(tmp_path, capsys):
    """Rule: `sweep --list` on a spec of millions of cells answers at once with exit 2 and one line."""
    path = _spec(tmp_path, HUGE)
    code, out, err = sweep(path, tmp_path / "out", capsys, "--list")
    assert code == 2 and "3,000,000 cells" in err and err.count("\n") == 1 and not out
    assert not (tmp_path / "out").exists()


def test_the_cap_is_raised_by_the_spec_key_or_the_flag(tmp_path, capsys):
    """Rule: `[sweep] max_cells` and `--max-cells` set the cap (12 cells: refused at 5, listed at 12);
    a cap that is not a positive integer is refused naming the key."""
    text = (
        '[sweep]\nwarmup = false\nmax_cells = 5\n[[accuracy]]\ncase = ["bar", "spin"]\ncells = [16, 32]\n'
        "cfl = [0.1, 0.2, 0.4]\n"
    )
    path = _spec(tmp_path, text)
    with pytest.raises(ConfigError, match="12 cells .* over the cap sweep.max_cells = 5"):
        expansion.expand(load_spec(path))
    assert len(expansion.expand(load_spec(path), max_cells=12)) == 12
    code, out, _ = sweep(path, tmp_path / "out", capsys, "--list", "--max-cells", "12")
    assert code == 0 and "12 cells in" in out
    for bad in ("0", "-3", "1.5", "true"):
        _spec(tmp_path, text.replace("max_cells = 5", f"max_cells = {bad}"))
        with pytest.raises(ConfigError) as info:
            load_spec(path)
        assert "sweep.max_cells" in one_line(info.value)


SCENES = '[sweep]\nwarmup = false\n[[scene]]\nconfig = "recontact"\nvariant = "full"\nseed = [{}]\n'.format(
    ", ".join(str(i) for i in range(2000))
)  # 2,000 scene cells: about ten seconds to resolve them all


def test_cells_are_made_one_at_a_time(tmp_path, monkeypatch):
    """Rule: expansion is lazy: the first scene cell comes after one scene config is resolved, not 2,000, and
    the progress callback knows the total from the start."""
    calls, seen = [0], []
    real = expansion.scene_config

    def counting(*args, **kwargs):
        calls[0] += 1
        return real(*args, **kwargs)

    monkeypatch.setattr(expansion, "scene_config", counting)
    cells = expansion.iter_cells(load_spec(_spec(tmp_path, SCENES)), progress=lambda k, n: seen.append((k, n)))
    first = next(cells)
    assert first.index == 0 and calls[0] == 1 and seen == [(1, 2000)]


def test_list_prints_each_cell_as_it_is_made(tmp_path, capsys, monkeypatch):
    """Rule: `--list` streams: the lines of the cells made before a failure are already printed (here the
    third cell's config is refused; a non-streaming list would print nothing before the error)."""
    real = expansion.scene_config

    def third_fails(*args, **kwargs):
        if args[8] == 2:  # seed
            raise ConfigError("", "scene[0]", "spec.toml: scene[0] seed 2 is refused by this test.")
        return real(*args, **kwargs)

    monkeypatch.setattr(expansion, "scene_config", third_fails)
    code, out, err = sweep(_spec(tmp_path, SCENES), tmp_path / "out", capsys, "--list")
    assert code == 2 and "seed 2 is refused" in err
    assert "up to 2,000 cells" in out and "seed 0" in out and "seed 1" in out, out


@pytest.mark.parametrize(
    "flags, named",
    [
        (["--list", "--fresh"], "--fresh"),
        (["--list", "--rerun-failed"], "--rerun-failed"),
        (["--list", "--rank-timeout", "60"], "--rank-timeout"),
        (["--fresh", "--rerun-failed"], "--rerun-failed"),
    ],
)
def test_sweep_flags_that_would_change_nothing_are_refused(flags, named, capsys):
    """--list only reads the cache, so --fresh, --rerun-failed and --rank-timeout beside it change nothing, and
    --rerun-failed beside --fresh (which reruns everything) neither: each is refused by name, exit 2."""
    from fracture_gs.cli import main

    assert main(["sweep", "accuracy", *flags]) == 2
    err = capsys.readouterr().err
    assert named in err and "Traceback" not in err and err.count("\n") == 1
