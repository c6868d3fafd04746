"""Bad input, round three (issue 34, item 5): the values a new user's probes found still getting through, each
refused where it enters in one sentence naming the key, flag or argument and the fix (docs/probes-round3.md
lists every probe). Each test fails on the code before the fix."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import torch
from badinput import capture_doc, one_line
from trainer_ply import write_cameras, write_trainer_ply

from fracture_gs.capture.fit import read_cameras
from fracture_gs.capture.scene import resolve
from fracture_gs.cli import main
from fracture_gs.errors import ArgumentError, ConfigError, FractureGSError, OutputError, SceneError
from fracture_gs.io.config import config_from_dict

pytestmark = pytest.mark.usefixtures("one_thread")


# ---------------------------------------------------------------- [capture] keys that would do nothing

UNUSED = [
    ({"view": 4}, "capture.view"),  # camera = "auto" frames the object itself
    ({"load": "none", "load_speed": 2.0}, "capture.load_speed"),
    ({"ground": "none", "ground_level": -10.0}, "capture.ground_level"),
]


@pytest.mark.parametrize("values, key", UNUSED, ids=[k for _, k in UNUSED])
def test_a_capture_key_the_rest_of_the_table_ignores_is_refused(values, key):
    """Rule: a [capture] key whose value the other keys make do nothing (a trainer view with the automatic
    camera, a load speed without a load, a ground level with the ground turned off) is a ConfigError naming it,
    as the ROI keys of another ROI kind already were."""
    with pytest.raises(ConfigError) as info:
        config_from_dict(capture_doc(**values), "probe.toml")
    assert key in one_line(info.value)


def test_the_same_keys_load_where_they_are_used():
    """Rule: the refusals are not too wide: a view with the trainer camera, a speed with a load, a ground level
    with the automatic ground, and a speed beside the config's own load of 0 all load as written."""
    cfg = config_from_dict(capture_doc(camera="trainer", view=4, load="pull", load_speed=2.0, ground_level=-10.0))
    assert (cfg.capture.view, cfg.capture.load_speed, cfg.capture.ground_level) == (4, 2.0, -10.0)


def test_load_speed_beside_the_configs_own_boundaries_is_refused():
    """Rule: with [[sim.boundaries]] of its own the config's boundaries are the load (capture.load is not
    added), so a capture.load_speed would change nothing: refused, naming it."""
    doc = capture_doc(load_speed=1.5)
    doc["sim"] = {"boundaries": [{"type": "plane", "point": [0.0, 0.0, 0.0], "normal": [0.0, 0.0, 1.0]}]}
    with pytest.raises(ConfigError) as info:
        config_from_dict(doc, "probe.toml")
    assert "capture.load_speed" in one_line(info.value) and "sim.boundaries" in str(info.value)


@pytest.fixture(scope="module")
def small_ply(tmp_path_factory):
    ply, _ = write_trainer_ply(tmp_path_factory.mktemp("round3_capture"), n=400)
    return ply


def test_a_ground_level_above_every_gaussian_is_a_scene_error(small_ply):
    """Rule: a capture.ground_level that leaves no Gaussian above it is refused naming the key (it ended in
    torch.quantile's 'input tensor must be non-empty' traceback)."""
    cfg = config_from_dict(capture_doc(str(small_ply), ground_level=1e6, up="-y"))
    with pytest.raises(SceneError) as info:
        resolve(cfg)
    assert "capture.ground_level" in one_line(info.value)


@pytest.mark.slow
def test_a_resolved_capture_with_a_load_speed_loads_again(small_ply):
    """Rule: resolve writes the load as boundaries and capture.load = "none"; the speed is in those boundaries,
    so capture.load_speed is written as 0 and the config a run writes (config.toml, `init`) loads back."""
    from fracture_gs.io.config.dump import config_to_dict

    doc = capture_doc(str(small_ply), cells_across=8, max_particles=300, load="pull", load_speed=0.7)
    cap = resolve(config_from_dict(doc))
    assert cap.cfg.capture.load == "none" and cap.cfg.capture.load_speed == 0.0
    grips = [b for b in cap.cfg.sim.boundaries if getattr(b, "velocity", None) is not None]
    assert sorted(abs(b.velocity[0]) for b in grips) == [0.7, 0.7], "the speed went into the grips"
    assert config_from_dict(config_to_dict(cap.cfg), "again").capture.load_speed == 0.0


# ---------------------------------------------------------------- cameras.json

GOOD = {
    "id": 0,
    "img_name": "v0",
    "width": 640,
    "height": 480,
    "position": [1.0, 2.0, 3.0],
    "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
    "fx": 500.0,
    "fy": 500.0,
}


def cameras(tmp_path, text: str | bytes) -> Path:
    path = tmp_path / "cameras.json"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


def view(**changes) -> str:
    return json.dumps([{**GOOD, **changes}])


CAMERA_PROBES = [
    (view().replace('"fx": 500.0', '"fx": 1' + "0" * 400), "fx"),  # an integer no float holds
    (view(position=[1e300, 0.0, 0.0]), "position"),
    ("[" * 100_000 + "]" * 100_000, "nest"),
]


@pytest.mark.parametrize("text, key", CAMERA_PROBES, ids=[k for _, k in CAMERA_PROBES])
def test_a_camera_value_no_trainer_writes_is_a_scene_error(tmp_path, text, key):
    """Rule: a view whose numbers overflow a float (a 400-digit integer: OverflowError before), a centre past
    1e9 scene units, or a file nested too deeply for the JSON parser (RecursionError before), is one SceneError
    naming the file and the key."""
    path = cameras(tmp_path, text)
    with pytest.raises(SceneError) as info:
        read_cameras(path)
    msg = one_line(info.value)
    assert msg.startswith(f"{path}: ") and key in msg


def test_a_cameras_json_with_a_bom_loads(tmp_path):
    """Rule: a UTF-8 byte-order mark (Windows editors write one) is not an error, as for configs."""
    (cam,) = read_cameras(cameras(tmp_path, b"\xef\xbb\xbf" + view(fx=321.5).encode()))
    assert (cam.width, cam.fx) == (640, 321.5)


def test_a_trainer_view_the_renderer_cannot_draw_names_the_view(tmp_path, small_ply):
    """Rule: capture.camera = "trainer" with a view whose focal length gives a field of view of 180° is a
    SceneError naming cameras.json, the view and the key (it was a ConfigError on render.camera.fov_deg, a key
    the user never wrote, naming no file)."""
    path = cameras(tmp_path, json.dumps([GOOD, {**GOOD, "fy": 1e-9}]))
    doc = capture_doc(str(small_ply), up="-y", camera="trainer", view=1, cameras_json=str(path), cells_across=8)
    with pytest.raises(SceneError) as info:
        resolve(config_from_dict(doc))
    msg = one_line(info.value)
    assert msg.startswith(f"{path}: camera 1") and "fy" in msg and "capture.view" in msg


TRAINER_PROBES = [
    ((640, 480, 1e300, 500.0), "fx"),  # a field of view of 0°
    ((640, 480, 500.0, 1e-9), "fy"),
    ((1, 100_000, 500.0, 500.0), "width"),  # a column of pixels: was "render.height = 64000000"
]


@pytest.mark.parametrize("numbers, key", TRAINER_PROBES, ids=[k for _, k in TRAINER_PROBES])
def test_check_view_names_the_key_the_renderer_cannot_draw(numbers, key):
    """Rule: check_view refuses a field of view outside 0.1°–179° on either axis and an image over 10:1, naming
    the file, the view and the key."""
    from fracture_gs.capture.fit import TrainerCamera, check_view

    w, h, fx, fy = numbers
    cam = TrainerCamera(torch.zeros(3, dtype=torch.float64), torch.eye(3, dtype=torch.float64), fx, fy, w, h, "v")
    with pytest.raises(SceneError) as info:
        check_view("c.json", 3, cam)
    msg = one_line(info.value)
    assert msg.startswith("c.json: camera 3 (v): ") and key in msg


def test_check_view_accepts_the_edges_of_its_ranges():
    """Rule: the ranges are not too tight: a 10:1 image and a 179° field of view are drawable; 10.1:1 is not."""
    from fracture_gs.capture.fit import TrainerCamera, check_view

    def cam(w, h, f):
        return TrainerCamera(torch.zeros(3, dtype=torch.float64), torch.eye(3, dtype=torch.float64), f, f, w, h)

    edge = 1000 / (2 * 114.5886501)  # tan(89.5°): 179° across 1000 px
    check_view("c.json", 0, cam(1000, 100, edge * 1.0000001))
    with pytest.raises(SceneError):
        check_view("c.json", 0, cam(1010, 100, 500.0))


def test_write_cameras_views_still_load(tmp_path):
    """Rule: the trainer-like views the other capture tests use are not refused by the new ranges."""
    path = tmp_path / "cameras.json"
    write_cameras(path, views=4)
    assert len(read_cameras(path)) == 4


# ---------------------------------------------------------------- sweep cache rows and flags


@pytest.fixture
def cached_cell(tmp_path):
    from fracture_gs.sweep import cache, expansion, load_spec

    spec = tmp_path / "spec.toml"
    spec.write_text('[[accuracy]]\ncase = "bar"\ncells = [16]\ncfl = 0.4\n')
    cell = expansion.expand(load_spec(spec))[0]
    row = {"status": "ok", "dt": 1e-3, "particles": 100, "substeps": 10, "wall_s": 1.0, "error": 0.01}
    return cell, {**row, "unit": "rel", "device": "cpu", "cell_s": 1.5}, cache


ROW_PROBES = [
    ("wall_s", -5.0),
    ("particles", -100),
    ("error", -0.3),
    ("dt", 0.0),
    ("cell_s", 10**400),
    ("substeps", 0),  # a finished accuracy cell simulated at least one substep
]


@pytest.mark.parametrize("key, value", ROW_PROBES, ids=[f"{k}={v!s:.12}" for k, v in ROW_PROBES])
def test_a_cached_row_with_a_value_no_run_writes_is_refused(tmp_path, cached_cell, key, value):
    """Rule: a cached row whose count or time is negative, whose step is zero, whose number overflows a float or
    whose finished accuracy cell simulated nothing is a damaged file: OutputError naming the file and the key
    (before, it was shown as a result, or overflowed in the tables)."""
    cell, row, cache = cached_cell
    path = cache.cache_path(tmp_path, cell.id)
    path.parent.mkdir()
    path.write_text(json.dumps({"id": cell.id, "params": cell.params, "row": {**row, key: value}}))
    with pytest.raises(OutputError) as info:
        cache.scan(tmp_path, [cell], "cpu")
    msg = one_line(info.value)
    assert msg.startswith(f"{path}: ") and key in msg


def test_a_sound_cached_row_is_still_reused(tmp_path, cached_cell):
    """Rule: the bounds are not too tight: the row a run writes (zero error is the exact answer) is reused."""
    cell, row, cache = cached_cell
    cache.store(tmp_path, cell, {**row, "error": 0.0})
    assert cache.scan(tmp_path, [cell], "cpu")[cell.id]["error"] == 0.0


@pytest.mark.parametrize("value", ["inf", "1e20", "604801"])
def test_rank_timeout_beyond_a_week_is_refused(value, capsys):
    """Rule: --rank-timeout inf (or any value past a week) is refused by the parser; before, inf was accepted and
    torch's timedelta overflowed at the rank meeting, reported as 'could not meet the other ranks'."""
    assert main(["sweep", "accuracy", "--list", "--rank-timeout", value]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--rank-timeout" in err and "604,800" in err


# ---------------------------------------------------------------- figures flags


@pytest.fixture
def no_figures_run(monkeypatch, tmp_path):
    import fracture_gs.paper.figures as figures

    calls = []
    monkeypatch.setattr(figures, "run_figures", lambda *a, **kw: calls.append("run") or {})
    monkeypatch.chdir(tmp_path)
    return calls


FIGURES_PROBES = [
    (["--only", ""], "--only is empty"),
    (["--only", "bread,"], "empty entry"),
    (["--only", "bench,bench"], "twice"),
    (["--only", "bench", "--backend", "torch"], "--backend"),
    (["--only", "interaction,fragments", "--backend", "warp"], "--backend"),
    (["--only", "bench", "--reuse"], "--reuse"),
    (["--only", "bread", "--backend", "gsplat", "--device", "cpu"], "--backend gsplat"),
    (["--readme-only", "--out", "no_figures_here"], "summary.json"),
    (["--out", ""], "--out is empty"),  # Path("") is the current folder: the figures went there
    (["--readme-only", "--out", " "], "--out is empty"),
]


@pytest.mark.parametrize("flags, words", FIGURES_PROBES, ids=[" ".join(f) for f, _ in FIGURES_PROBES])
def test_figures_flags_that_would_do_nothing_or_fail_late_are_refused(no_figures_run, capsys, flags, words):
    """Rule: `figures --only ''` ran every group (minutes), a group named twice, --backend where no group draws a
    scene panel, --reuse where no group has a cached run, --backend gsplat on the CPU (failed after simulating)
    and --readme-only on a folder without summary.json are each one line and exit 2, before anything runs."""
    assert main(["figures", *flags]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and words in err, err
    assert no_figures_run == [] and not Path("no_figures_here").exists()


def test_figures_groups_that_use_the_flags_still_run(no_figures_run):
    """Rule: --backend with a scene-panel group and --reuse with a simulated group still reach run_figures."""
    assert main(["figures", "--only", "bread,bench", "--backend", "torch", "--reuse", "--device", "cpu"]) == 0
    assert no_figures_run == ["run"]


# ---------------------------------------------------------------- Python API


@pytest.fixture(scope="module")
def bread():
    import fracture_gs as fgs
    from fracture_gs.io.config import load_config

    cfg = load_config("bread")
    cfg.particles, cfg.frames = 300, 1
    return cfg, fgs.assets.build("bread", n=300, seed=0)


def call(sim, gs, **changes):
    args = dict(means=gs.means, opacities=gs.opacities, sh=gs.sh, quats=gs.quats, scales=gs.scales)
    return sim(**{**args, **changes})


def test_fracture_sim_refuses_an_empty_variant_and_a_foreign_topology(bread):
    """Rule: FractureSim(variant="") is an unknown variant, not the config's default (it was silently
    replaced), and a topology that is not a Topology or a list of them is an ArgumentError at construction
    (it was an AttributeError inside the first frame)."""
    from fracture_gs import FractureSim

    cfg, _ = bread
    for kwargs, word in (({"variant": ""}, "variant"), ({"topology": "topology.npz"}, "topology")):
        with pytest.raises(ArgumentError) as info:
            FractureSim(cfg, device="cpu", **kwargs)
        assert word in one_line(info.value)


EDITS = [
    (lambda c: setattr(c, "frames", 0), "frames"),  # returned frame 0 alone
    (lambda c: setattr(c, "frame_dt", float("nan")), "frame_dt"),  # ValueError from math.ceil
    (lambda c: setattr(c.sim, "gravity", (0.0, 0.0)), "sim.gravity"),  # Warp's vector constructor
    (lambda c: setattr(c, "frames", "2"), "frames"),  # TypeError in range()
    (lambda c: setattr(c.material, "model", "rubber"), "material.model"),  # KeyError
    (lambda c: setattr(c.sim, "cfl", 7.0), "sim.cfl"),  # ran at CFL 7
]


@pytest.mark.parametrize("edit, key", EDITS, ids=[k for _, k in EDITS])
def test_a_config_edited_in_python_is_checked_like_a_file(bread, edit, key):
    """Rule: FractureSim checks its config as the loader checks a file (types, shapes and values) when it runs,
    so a config edited after loading is one ConfigError naming the key, not a torch/Warp/Python traceback or
    a run with a value the CLI would refuse."""
    from fracture_gs import FractureSim

    cfg, gs = bread
    cfg = copy.deepcopy(cfg)
    sim = FractureSim(cfg, variant="baseline", device="cpu")
    edit(sim.cfg)
    with pytest.raises(ConfigError) as info:
        call(sim, gs)
    assert key in one_line(info.value)


def test_near_zero_quaternions_are_refused(bread):
    """Rule: a quaternion whose norm is below torch.normalize's eps (1e-12) has lost its rotation (normalize
    returns ≈ 0 and the rotation matrix becomes the identity), so it is refused like a zero one; a quaternion of
    norm 1e-6 still gives its rotation."""
    from fracture_gs import FractureSim

    cfg, gs = bread
    sim = FractureSim(cfg, variant="baseline", device="cpu")
    with pytest.raises(ArgumentError) as info:
        call(sim, gs, quats=gs.quats * 1e-30)
    assert "quats" in one_line(info.value)
    small = call(sim, gs, quats=gs.quats * 1e-6)["covars"][0]
    assert torch.allclose(small, call(sim, gs)["covars"][0], rtol=1e-3, atol=1e-8)


def test_api_arguments_of_the_wrong_kind_are_argument_errors(bread, tmp_path):
    """Rule: the package's entry points refuse a device this machine lacks (torch raised AssertionError), an
    unknown device type, a non-path config name (TypeError), a non-GaussianSet, and a fractional or textual
    particle count or seed, each in one sentence naming the argument."""
    from fracture_gs import assets, pipeline
    from fracture_gs.io import load_config
    from fracture_gs.io.ply import load_ply, save_ply
    from fracture_gs.sim import Particles

    cfg, gs = bread
    ply = tmp_path / "g.ply"
    save_ply(gs, ply)
    probes = [
        (lambda: load_ply(ply, device="cuda:99"), "device"),
        (lambda: pipeline.prepare_scene(cfg, device="tpu"), "device"),
        (lambda: load_config(123), "path_or_name"),
        (lambda: Particles.from_gaussians([1, 2], cfg), "gs"),
        (lambda: assets.build("bread", n=2.5), "n = 2.5"),
        (lambda: assets.build("bread", n=200, seed="a"), "seed"),
    ]
    for fn, word in probes:
        with pytest.raises(FractureGSError) as info:
            fn()
        assert word in one_line(info.value)


# ---------------------------------------------------------------- a flag typed twice

REPEATED = [
    ["render-sim", "bread", "--frames-png", "--no-frames-png"],  # ran with the last one, the first did nothing
    ["render-sim", "bread", "--device", "cpu", "--device=cuda:0"],
    ["render-sim", "bread", "--frames", "2", "--frames", "3"],
    ["sweep", "accuracy", "--list", "--max-cells", "3", "--max-c", "4"],  # an abbreviation is the same flag
    ["figures", "--only", "bread", "--only", "bench"],
]


@pytest.mark.parametrize("argv", REPEATED, ids=[" ".join(a[2:]) for a in REPEATED])
def test_a_flag_typed_twice_with_different_values_is_refused(argv, capsys, monkeypatch):
    """Rule: argparse keeps the last of a repeated flag, so a first one with another value (or the other half of
    --frames-png/--no-frames-png) would do nothing: one line naming both, exit 2, before anything runs."""
    import fracture_gs.cli as cli

    monkeypatch.setattr(cli, "_commands", lambda: pytest.fail("a command ran"))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "only the last one typed would count" in err, err


def test_a_flag_typed_twice_with_the_same_value_passes(capsys, monkeypatch):
    """Rule: the same flag with the same value twice changes nothing and is not refused (it reaches the command)."""
    import fracture_gs.cli as cli

    ran = []
    monkeypatch.setattr(cli, "_commands", lambda: {"validate": lambda args: ran.append(args.config) or 0})
    assert main(["validate", "--dump", "--dump", "bread"]) == 0 and ran == ["bread"]
