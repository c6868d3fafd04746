"""Bad input, round four (issue 34, item 5): the CLI flags, output folders and Python API values a new user's probes
still found getting through (docs/probes-round4.md). Each refusal is one sentence naming the flag or argument and
the fix, before any work; each test fails on the code before the fix."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch
from badinput import one_line
from trainer_ply import write_trainer_ply

from fracture_gs.cli import main
from fracture_gs.errors import ArgumentError, FractureGSError, OutputError, RenderError

pytestmark = pytest.mark.usefixtures("one_thread")


def cli_refusal(argv, capsys) -> str:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0 and err.startswith("fracture-gs: error: "), (code, err)
    return err


@pytest.fixture
def nothing_runs(monkeypatch):
    """The heavy entry points replaced by failures: a refusal must come before any of them."""
    import fracture_gs.paper.accuracy as accuracy
    import fracture_gs.paper.bench as bench
    import fracture_gs.paper.readme as readme

    def ran(*a, **kw):
        raise AssertionError("the command ran instead of refusing")

    for mod, name in ((accuracy, "run_accuracy"), (accuracy, "write_outputs"), (bench, "run_bench")):
        monkeypatch.setattr(mod, name, ran)
    monkeypatch.setattr(readme, "refresh_readme", ran)
    monkeypatch.delenv("FRACTURE_GS_DEBUG", raising=False)


# ---------------------------------------------------------------- flags


FLAGS = [
    (["render-sim", "bread", "--particles", "abc"], "like --particles"),  # the example named --frames
    (["render-sim", "bread", "--export-ply", "1.5"], "like --export-ply"),
    (["bench", "--steps", "x"], "like --steps"),
    (["bench", "--grid", "2"], "--grid"),  # particles outside the grid, naming sim.grid_origin
    (["bench", "--grid", "100000"], "--grid"),  # "sim.grid_shape would be 1e+15 nodes", naming sim.max_grid_cells
    (["bench", "--particles", str(10**10)], "--particles"),  # torch's allocator failed after seconds
    (["render-sim", "bread", "--variants", "full,"], "empty entry"),  # ran 'full' alone without a word
    (["bench", "--accuracy", "--cases", ""], "--cases is empty"),  # ran every case (minutes)
    (["bench", "--accuracy", "--cases", "bar,bar"], "twice"),  # ran bar once, silently
    (["bench", "--accuracy", "--cases", "bar,"], "empty entry"),
    (["bench", "--accuracy", "--from-json", ""], "--from-json is empty"),  # ran the whole sweep
]


@pytest.mark.parametrize("argv, words", FLAGS, ids=[" ".join(a[1:]) for a, _ in FLAGS])
def test_a_flag_value_is_refused_by_name_before_any_work(argv, words, nothing_runs, tmp_path, capsys):
    """Rule: a count flag's example names that flag; bench --grid and --particles are bounded (5-node grids,
    10^15 nodes and 10^10 particles failed late, naming config keys); a comma list with an empty or repeated
    entry, an empty --cases and an empty --from-json are refused (they ran something else without a word)."""
    err = cli_refusal([*argv, "--out", tmp_path / "out"], capsys)
    assert words in err, err


BAD_JSON = [
    ("folder", None, "is a folder"),  # IsADirectoryError traceback
    ("text", "{", "is not JSON"),  # "internal error: JSONDecodeError"
    ("object", "{}", "not a saved accuracy sweep"),  # KeyError traceback
    ("list", "[]", "not a saved accuracy sweep"),
    (
        "result",
        json.dumps({"results": [{"case": "bar"}], "caption": "", "command": "", "device_name": ""}),
        "results[0]",
    ),
]


@pytest.mark.parametrize("kind, text, words", BAD_JSON, ids=[k for k, _, _ in BAD_JSON])
def test_bench_from_json_names_a_file_it_cannot_redraw(kind, text, words, nothing_runs, tmp_path, capsys):
    """Rule: --from-json takes the accuracy.json a sweep wrote; a folder, a file that is not JSON, or JSON of another
    shape is one line naming the flag and the file (each was a traceback)."""
    path = tmp_path / "saved.json"
    path.mkdir() if text is None else path.write_text(text)
    err = cli_refusal(["bench", "--accuracy", "--from-json", path, "--out", tmp_path / "out"], capsys)
    assert "--from-json" in err and words in err, err


@pytest.mark.parametrize("text", ["{", "[]", "{}", json.dumps({"meta": {"command": "x"}})])
def test_figures_readme_only_names_a_damaged_summary(text, nothing_runs, tmp_path, capsys):
    """Rule: --readme-only reads summary.json; one that is not JSON, not an object or lacks the run's meta is one
    line naming the file (JSONDecodeError, AttributeError and KeyError tracebacks before)."""
    (tmp_path / "summary.json").write_text(text)
    err = cli_refusal(["figures", "--readme-only", "--out", tmp_path], capsys)
    assert "summary.json" in err, err


@pytest.fixture(scope="module")
def ply(tmp_path_factory):
    path, _ = write_trainer_ply(tmp_path_factory.mktemp("round4_cli"), n=400)
    return path


def test_init_never_overwrites_its_own_scene(ply, tmp_path, capsys):
    """Rule: `init scene.ply --out scene.ply --force` would replace the scene with its TOML (it did, and printed
    "wrote scene.ply"); refused naming --out, the scene left as it was."""
    before = ply.read_bytes()
    err = cli_refusal(["init", ply, "--out", ply, "--force"], capsys)
    assert "--out" in err and "scene file itself" in err and ply.read_bytes() == before


@pytest.mark.parametrize("command", ["render-sim", "sweep", "figures", "init"])
def test_an_out_path_the_system_cannot_name_is_one_line(command, tmp_path, capsys, monkeypatch):
    """Rule: an --out whose name is over the file system's 255 bytes is one OutputError line (an OSError
    "File name too long" traceback before, from the first exists())."""
    monkeypatch.chdir(tmp_path)
    long = tmp_path / ("n" * 300)
    target = {"render-sim": ["render-sim", "bread"], "figures": ["figures", "--only", "bench"]}.get(command)
    if command == "sweep":
        (tmp_path / "s.toml").write_text('[[accuracy]]\ncase = "bar"\ncells = [8]\ncfl = 0.4\n')
        target = ["sweep", "s.toml", "--device", "cpu"]
    if command == "init":
        target, long = ["init", ply_path(tmp_path)], Path(str(long) + ".toml")
    err = cli_refusal([*target, "--out", long], capsys)
    assert "--out" in err and "cannot be used as a path" in err, err


def ply_path(folder: Path) -> Path:
    path, _ = write_trainer_ply(folder / "m", n=200)
    return path


def test_sweep_refuses_an_empty_out_and_a_lone_rank_timeout(tmp_path, capsys, monkeypatch):
    """Rule: `sweep --out ''` wrote the cache and tables into the current folder (Path("") is "."), and
    --rank-timeout in a single process (no other ranks) did nothing; both are refused before any cell runs."""
    import fracture_gs.sweep.driver as driver

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(driver, "run_sweep", lambda *a, **kw: pytest.fail("a cell ran"))
    (tmp_path / "s.toml").write_text('[[accuracy]]\ncase = "bar"\ncells = [8]\ncfl = 0.4\n')
    assert "--out is empty" in cli_refusal(["sweep", "s.toml", "--out", "", "--device", "cpu"], capsys)
    err = cli_refusal(["sweep", "s.toml", "--rank-timeout", "60", "--out", "o", "--device", "cpu"], capsys)
    assert "--rank-timeout" in err and "single-process" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize("name", ["sweep.md", "sweep_pareto.png"])
def test_sweep_checks_its_table_files_before_the_cells(name, tmp_path, capsys, monkeypatch):
    """Rule: the tables are written after every cell; a folder where one goes was an IsADirectoryError traceback
    at the end. It is refused before any cell runs."""
    import fracture_gs.sweep.driver as driver

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(driver, "run_sweep", lambda *a, **kw: pytest.fail("a cell ran"))
    (tmp_path / "s.toml").write_text('[[accuracy]]\ncase = "bar"\ncells = [8]\ncfl = 0.4\n')
    (tmp_path / "o" / name).mkdir(parents=True)
    err = cli_refusal(["sweep", "s.toml", "--out", "o", "--device", "cpu"], capsys)
    assert name in err and "a folder" in err, err


# ---------------------------------------------------------------- render-sim: outputs checked before the scene

IN_THE_WAY = [
    ("summary.json", "dir", {}),  # IsADirectoryError after the run
    ("comparison.mp4", "dir", {}),  # ffmpeg failed; the run still said "outputs in ...: comparison.mp4"
    ("config.toml", "dir", {}),
    ("metrics.jsonl", "dir", {}),
    ("view", "file", {}),  # FileExistsError from mkdir
    ("frames", "file", {"frames_png": True}),
]


@pytest.mark.parametrize("name, kind, extra", IN_THE_WAY, ids=[n for n, _, _ in IN_THE_WAY])
def test_render_sim_checks_its_outputs_before_the_scene(name, kind, extra, tmp_path, monkeypatch):
    """Rule: a folder where render-sim writes a file (or a file where it makes a folder) is one OutputError naming
    it, raised before the scene is prepared (before: a traceback, or a silently missing video, after the run)."""
    import fracture_gs.render_sim.job as job
    from fracture_gs.io.config import load_config

    monkeypatch.setattr(job, "prepare_scene", lambda *a, **kw: pytest.fail("the scene was prepared"))
    (tmp_path / name).mkdir() if kind == "dir" else (tmp_path / name).write_text("x")
    with pytest.raises(OutputError) as info:
        job.run_render_sim(load_config("bread"), ["baseline"], "cpu", tmp_path, progress=False, **extra)
    assert f"named {name}" in str(info.value)


def test_render_sim_refuses_a_comparison_too_wide_to_encode(tmp_path, monkeypatch):
    """Rule: three 8192-pixel panels side by side (24,584 px) are wider than libx264 encodes (16,384); refused
    naming render.width before the run (it was "writing the video stopped after 2 frames" after the run)."""
    import fracture_gs.render_sim.job as job
    from fracture_gs.io.config import load_config

    monkeypatch.setattr(job, "prepare_scene", lambda *a, **kw: pytest.fail("the scene was prepared"))
    cfg = load_config("bread")
    cfg.render.width, cfg.render.height = 8192, 2
    with pytest.raises(RenderError) as info:
        job.run_render_sim(cfg, ["baseline", "stress_zero", "full"], "cpu", tmp_path, progress=False)
    assert "render.width = 8192" in one_line(info.value) and "5458" in str(info.value)


# ---------------------------------------------------------------- Python API


@pytest.fixture(scope="module")
def bread():
    import fracture_gs as fgs
    from fracture_gs.io.config import load_config

    cfg = load_config("bread")
    cfg.particles, cfg.frames = 200, 1
    return cfg, fgs.assets.build("bread", n=200, seed=0)


def test_fracture_sim_takes_a_path_and_refuses_a_flag_that_is_not_a_bool(bread):
    """Rule: FractureSim(pathlib.Path) loads the config like the string (it was refused: "cfg must be a
    SceneConfig, got PosixPath"); differentiable="no" or diagnostics="off" (truthy strings that turned the
    mode on) are ArgumentErrors."""
    from fracture_gs import FractureSim
    from fracture_gs.io.config import CONFIG_DIR

    assert FractureSim(CONFIG_DIR / "bread.toml").cfg.name == "bread"
    for kwargs in ({"differentiable": "no"}, {"diagnostics": "off"}):
        with pytest.raises(ArgumentError) as info:
            FractureSim("bread", **kwargs)
        assert next(iter(kwargs)) in one_line(info.value)


def test_labels_without_a_map_change_nothing_and_labels_that_wrap_are_refused(bread):
    """Rule: labels pick a material_map entry. With no map they are the scene's own data passed through (the
    documented `labels=gs.labels`): accepted, and the run is the one without them. A label past int32 would wrap onto
    another label (2**40 became 0) when stored: an ArgumentError naming int32."""
    import copy

    from fracture_gs import FractureSim
    from fracture_gs.io.gaussian_set import check_gaussians

    cfg, gs = bread
    plain = copy.deepcopy(cfg)
    plain.material_map = []
    plain.frames = 2
    args = dict(means=gs.means, opacities=gs.opacities, sh=gs.sh, quats=gs.quats, scales=gs.scales)
    labelled = FractureSim(plain, variant="baseline", device="cpu")(**args, labels=torch.arange(len(gs)) % 3)
    bare = FractureSim(plain, variant="baseline", device="cpu")(**args)
    assert torch.equal(labelled["means"], bare["means"]) and torch.equal(labelled["covars"], bare["covars"])
    with pytest.raises(ArgumentError) as info:
        check_gaussians("f", means=gs.means, labels=torch.full((len(gs),), 2**40))
    assert "int32" in one_line(info.value)


def test_a_velocity_past_ten_km_per_second_is_refused():
    """Rule: the differentiable forward's velocity is at most 10 km/s (1e30 made the CFL substep 0 and raised
    ZeroDivisionError inside the solver); 9 km/s still passes."""
    from fracture_gs.module import _velocity_argument

    assert _velocity_argument([9e3, 0.0, 0.0], 5).shape == (3,)
    with pytest.raises(ArgumentError) as info:
        _velocity_argument([1e30, 0.0, 0.0], 5)
    assert "velocity" in one_line(info.value)


def test_api_values_are_refused_by_name(bread, tmp_path):
    """Rule: the public functions refuse a bad mask, device, size, count, spacing, threshold, config or particles
    in one sentence naming the argument (each was a torch/Python traceback, or a value used without a word)."""
    import fracture_gs as fgs
    from fracture_gs import pipeline
    from fracture_gs.capture.scene import resolve
    from fracture_gs.io import dump_config
    from fracture_gs.sim import Particles, Simulator

    cfg, gs = bread
    probes = [
        (lambda: gs.subset(torch.ones(5, dtype=torch.bool)), "mask"),
        (lambda: gs.subset(torch.ones(len(gs))), "mask"),
        (lambda: gs.to("tpu"), "device"),
        (lambda: dump_config("bread"), "cfg"),
        (lambda: fgs.assets.build("bread", size="huge", n=100), "size"),  # ignored when n was given
        (lambda: fgs.assets.build("bread", n=10, device="tpu"), "device"),
        (lambda: fgs.assets.build("bread", n=2 * 10**8), "n ="),
        (lambda: fgs.assets.fill_interior(gs, spacing=-1.0), "spacing"),  # used the default spacing silently
        (lambda: fgs.assets.fill_interior(gs, spacing=float("nan")), "spacing"),
        (lambda: fgs.assets.fill_interior(gs, threshold=-1.0), "threshold"),  # filled everything
        (lambda: fgs.assets.fill_interior(gs, closing=100), "closing"),  # 100 dilations of a 460³ grid: > 10 min
        (lambda: fgs.assets.fill_interior(gs, max_grid=10**6), "max_grid"),
        (lambda: fgs.assets.fill_interior("gs"), "gs"),
        (lambda: Simulator({"dt": 1e-4}, Particles.from_gaussians(gs, cfg), device="cpu"), "cfg"),
        (lambda: Simulator(cfg.sim, None, device="cpu"), "particles"),
        (lambda: pipeline.prepare_scene("bread"), "cfg"),
        (lambda: resolve("scene.ply"), "cfg"),  # AttributeError
        (lambda: resolve(cfg, "tpu"), "device"),  # taken for the CPU's budget without a word
    ]
    for fn, word in probes:
        with pytest.raises(FractureGSError) as info:
            fn()
        assert word in one_line(info.value), str(info.value)


def test_render_arguments_are_refused_by_name(bread):
    """Rule: render's cameras take whole image sides, a field of view in (0°, 180°), finite points and a non-zero
    up and radius; render() takes [N, 3] colours, [N] opacities, tensors, a Camera and an RGB background; sh_colors
    a square K up to 16. Each was a traceback (ZeroDivisionError, shape errors) or a camera of NaN or 0 pixels."""
    from fracture_gs import render as R

    cfg, gs = bread
    cam = R.look_at((0.5, -1.0, 0.5), (0.5, 0.5, 0.3), width=32, height=24)
    cov, col = gs.covariances(), torch.rand(len(gs), 3)
    probes = [
        (lambda: R.look_at((0, -1, 0), (0, 0, 0), width=0), "width"),
        (lambda: R.look_at((0, -1, 0), (0, 0, 0), fov_deg=0.0), "fov_deg"),
        (lambda: R.look_at((0, -1, 0), (0, 0, 0), fov_deg=180.0), "fov_deg"),
        (lambda: R.look_at((float("nan"), -1, 0), (0, 0, 0)), "eye"),
        (lambda: R.look_at((0, -1, 0), (0, 0, 0), up=(0, 0, 0)), "up"),
        (lambda: R.orbit((0, 0, 0), -1.0, 20.0, 0.0), "radius"),
        (lambda: R.render(gs.means, cov, torch.rand(len(gs), 4), gs.opacities, cam), "colors"),
        (lambda: R.render(gs.means, cov, col, torch.rand(len(gs) + 1), cam), "opacities"),
        (lambda: R.render(gs.means.tolist(), cov, col, gs.opacities, cam), "means"),
        (lambda: R.render(gs.means, cov, col, gs.opacities, None), "camera"),
        (lambda: R.render(gs.means, cov, col, gs.opacities, cam, background=(1.0, 1.0)), "background"),
        (lambda: R.sh_colors(torch.zeros(10, 5, 3), torch.zeros(10, 3), torch.zeros(3)), "sh"),
    ]
    for fn, word in probes:
        with pytest.raises(RenderError) as info:
            fn()
        assert word in one_line(info.value), str(info.value)
    assert R.render(gs.means, cov, col, gs.opacities, cam).image.shape == (24, 32, 3)


# ---------------------------------------------------------------- Ctrl-C inside a finalizer


def test_ctrl_c_inside_a_finalizer_prints_no_traceback(monkeypatch):
    """Rule: a Ctrl-C that lands inside a `__del__` (render-sim on a capture, 6 s in: a tensor's finalizer) made
    the handler raise there, and Python printed "Exception ignored in ... Traceback ... KeyboardInterrupt" before
    the one-line message. Both handlers now only record it there: no unraisable exception, the run's stop event
    set (render-sim stops at its next frame) and main's check still raises it (exit 130)."""
    import signal
    import sys

    from fracture_gs import cli
    from fracture_gs.cli.run import sigint_event

    dropped = []
    monkeypatch.setattr(sys, "unraisablehook", lambda u: dropped.append(u.exc_type))

    class Finalized:
        def __init__(self, handler):
            self.handler = handler

        def __del__(self):
            self.handler(signal.SIGINT, sys._getframe())

    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal (pytest may run in the background)
    try:
        with sigint_event() as stop:
            Finalized(signal.getsignal(signal.SIGINT))  # made and dropped at once: its __del__ runs here
        interrupts = cli._Interrupts()
        Finalized(interrupts._handler)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert dropped == [] and stop.is_set() and interrupts.hit
    with pytest.raises(KeyboardInterrupt):
        interrupts.check()


def test_a_ctrl_c_before_the_first_file_says_nothing_was_written(monkeypatch, tmp_path, capsys):
    """Rule: a Ctrl-C after render-sim made its output folder but before it wrote a file said "partial outputs
    are in <an empty folder>" (render-sim bread, 5 s in); it says nothing was written, and exits 130."""
    from fracture_gs import render_sim as runner

    def interrupted(*a, **kw):
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_render_sim", interrupted)
    assert main(["render-sim", "bread", "--device", "cpu", "--out", str(tmp_path / "run")]) == 130
    err = capsys.readouterr().err.strip()
    assert err.endswith("interrupted; nothing was written.") and (tmp_path / "run").is_dir()
