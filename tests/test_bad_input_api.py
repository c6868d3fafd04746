"""Bad input, round two (issue 34 item 5): flags that would do nothing, the Python API's shapes and values,
path arguments, and Ctrl-C during the imports. Every refusal is one sentence naming the flag or argument:
exit 2 from the CLI (before any simulation starts), a `fracture_gs.errors` exception from the Python API."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
from fuzzutil import ok_summary

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.errors import ArgumentError, FractureGSError, SimulationError
from fracture_gs.io import GaussianSet, detect_format, load_ply, read_gaussians, save_ply, write_gaussians
from fracture_gs.io.config import load_config
from fracture_gs.io.formats import is_splat_file
from fracture_gs.io.ply import load_ply_lenient
from fracture_gs.module import FractureSim, _material_argument, gaussians_from_tensors

ROOT = Path(__file__).resolve().parents[1]
SPZ = ROOT / "tests" / "data" / "captures" / "biker_5k.spz"
N = 6


# ----------------------------------------------------------------------------- CLI: flags that do nothing


@pytest.fixture
def scenes(tmp_path):
    """Captured-scene configs in which a capture flag does nothing: fit off, resolution fixed, own load."""
    spz = SPZ.as_posix()
    files = {
        "FIT_FALSE": f'extends = "capture"\nscene = "{spz}"\n[capture]\nfit = false\n',
        "CELLS": f'extends = "capture"\nscene = "{spz}"\n[capture]\ncells_across = 40\n',
        "GRIPS": f'extends = "bread"\nscene = "{spz}"\n',  # bread's two grips are its load
    }
    out = {}
    for name, text in files.items():
        (tmp_path / f"{name.lower()}.toml").write_text(text)
        out[name] = str(tmp_path / f"{name.lower()}.toml")
    out["SPZ"] = str(SPZ)
    return out


@pytest.fixture
def no_run(monkeypatch):
    """The heavy entry points replaced by recorders: a refusal must come before any of them."""
    import fracture_gs.paper.bench as bench
    import fracture_gs.paper.figures as figures

    calls = []
    monkeypatch.setattr(
        runner,
        "run_render_sim",
        lambda cfg, variants, device, out_dir, **kw: (
            calls.append(("render-sim", cfg, device, kw)) or ok_summary(cfg, variants, device)
        ),
    )
    monkeypatch.setattr(bench, "run_bench", lambda **kw: calls.append(("bench", kw)) or {"ok": True})
    monkeypatch.setattr(figures, "run_figures", lambda device, out_dir, **kw: calls.append(("figures", kw)) or {})
    monkeypatch.delenv("FRACTURE_GS_DEBUG", raising=False)
    return calls


@pytest.fixture
def two_gpus(monkeypatch):
    """This CPU machine pretends to have cuda:0 and cuda:1 (only the device check sees them)."""
    from fracture_gs.cli import devices

    monkeypatch.setattr(devices, "_cuda_devices", lambda: (True, 2, "pretended"))
    monkeypatch.setattr(devices, "_prepare_warp", lambda init=True: None)


REFUSED = [
    (["render-sim", "bread", "--load", "drop"], "--load", "captured scenes"),
    (["render-sim", "bread", "--material", "wood"], "--material", "captured scenes"),
    (["render-sim", "bread", "--quality", "fine"], "--quality", "captured scenes"),
    (["render-sim", "SPZ", "--particles", "500"], "--particles", "captured scene"),
    (["render-sim", "SPZ", "--preset", "paper"], "--preset", "--quality"),
    (["render-sim", "FIT_FALSE", "--load", "drop"], "--load", "capture.fit = false"),
    (["render-sim", "FIT_FALSE", "--material", "wood"], "--material", "capture.fit = false"),
    (["render-sim", "CELLS", "--quality", "fine"], "--quality", "cells_across = 40"),
    (["render-sim", "GRIPS", "--load", "drop"], "--load", "sim.boundaries"),
    (["render-sim", "bread", "--frames", "3", "--export-ply", "4"], "--export-ply 4", "last frame of this run (3)"),
    (["render-sim", "bread", "--devices", "cpu,cpu"], "--devices cpu,cpu", "names cpu twice"),
    (["render-sim", "bread", "--devices", "cuda,cuda:0"], "--devices cuda,cuda:0", "names cuda:0 twice"),
    (["render-sim", "bread", "--devices", "cpu,cuda:0", "--schedule", "threads"], "--schedule threads", "--devices"),
    (["render-sim", "bread", "--devices", "cpu,cuda:0", "--schedule", "in-turn"], "--schedule in-turn", "--devices"),
    (["render-sim", "bread", "--device", "cuda:1", "--devices", "cpu,cuda:0"], "--device cuda:1", "--devices"),
    (["render-sim", "bread", "--variants", "full", "--devices", "cpu,cuda:0"], "--devices", "sit idle"),
    (["render-sim", "bread", "--devices", "cpu,"], "--devices", "empty entry"),
    (["render-sim", "bread", "--variants", "full", "--schedule", "threads"], "--schedule threads", "one variant"),
    (["render-sim", "bread", "--resolution", "-64x48"], "--resolution", "WxH with positive integers, got -64x48"),
    (["render-sim", "bread", "--resolution", "0x48"], "--resolution", "WxH with positive integers, got 0x48"),
    (["bench", "--accuracy", "--steps", "5"], "--steps", "--accuracy"),
    (["bench", "--accuracy", "--no-graph"], "--no-graph", "--accuracy"),
    (["bench", "--accuracy", "--sort", "interleaved"], "--sort", "--accuracy"),
    (["bench", "--quick"], "--quick", "--accuracy"),
    (["bench", "--cases", "bar"], "--cases", "--accuracy"),
    (["bench", "--device", "cpu", "--no-graph"], "--no-graph", "CPU"),
    (["bench", "--accuracy", "--from-json", "x.json", "--quick"], "--quick", "--from-json"),
    (["bench", "--accuracy", "--from-json", "x.json", "--device", "cpu"], "--device", "--from-json"),
    (["figures", "--readme-only", "--only", "ficus"], "--only", "--readme-only"),
    (["figures", "--readme-only", "--device", "cpu"], "--device", "--readme-only"),
]


@pytest.mark.parametrize("argv,flag,why", REFUSED, ids=[" ".join(a) for a, _, _ in REFUSED])
def test_a_flag_that_would_do_nothing_is_refused(argv, flag, why, scenes, no_run, two_gpus, tmp_path, capsys):
    """Rule: a flag the run would silently drop is a user error: exit 2, one line that names the flag and why,
    no traceback, and nothing simulated, benchmarked or drawn (the refusal comes first)."""
    argv = [scenes.get(a, a) for a in argv] + ["--out", str(tmp_path / "out")]
    code = cli.main(argv)
    out, err = capsys.readouterr()
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("fracture-gs: error: "), (code, err)
    assert flag in lines[0] and why in lines[0] and "Traceback" not in out + err, lines[0]
    assert no_run == []


ACCEPTED = [
    (["render-sim", "bread", "--particles", "500", "--frames", "4", "--export-ply", "4", "--schedule", "threads"]),
    (["render-sim", "SPZ", "--load", "drop", "--material", "wood", "--quality", "draft"]),
    (["render-sim", "FIT_FALSE", "--preset", "paper"]),
    (["render-sim", "bread", "--devices", "cpu,cuda:0"]),
    (["render-sim", "bread", "--device", "cpu", "--schedule", "in-turn", "--resolution", "64x48"]),
]


@pytest.mark.parametrize("argv", ACCEPTED, ids=[" ".join(a) for a in ACCEPTED])
def test_flags_that_act_still_reach_the_run(argv, scenes, no_run, two_gpus, tmp_path, capsys):
    """Rule (no false refusal): the same flags where they act reach the runner with their values — a
    built-in scene's --particles, a capture's --load/--material/--quality, --preset when capture.fit is off,
    two distinct --devices, --schedule on one device."""
    argv = [scenes.get(a, a) for a in argv] + ["--out", str(tmp_path / "out")]
    assert cli.main(argv) == 0, capsys.readouterr().err
    ((_, cfg, device, kw),) = no_run
    given = dict(zip(argv[2::2], argv[3::2]))
    if "--particles" in given:
        assert cfg.particles == 500 and kw["export_ply"] == 4 and kw["schedule"] == "threads"
    if "--load" in given:
        assert (cfg.capture.load, cfg.capture.material, cfg.capture.quality) == ("drop", "wood", "draft")
    if "--preset" in given:
        assert cfg.preset == "paper" and cfg.sim.dx == pytest.approx(1 / 128)
    if "--devices" in given:
        assert kw["devices"] == ["cpu", "cuda:0"] and device == "cpu" and "schedule" not in kw
    if "--resolution" in given:
        assert (cfg.render.width, cfg.render.height) == (64, 48) and kw["schedule"] == "in_turn"


def test_bench_applies_its_defaults_to_the_flags_not_typed(no_run, tmp_path, capsys):
    """bench's flags default to None (so a typed flag is told from one not typed); the documented defaults
    (200 steps, 20 warm-up, 3 trials, 128³, cell order) still reach the benchmark, a typed value replaces one."""
    assert cli.main(["bench", "--device", "cpu", "--steps", "7", "--out", str(tmp_path)]) == 0, capsys.readouterr()
    ((_, kw),) = no_run
    assert (kw["steps"], kw["warmup"], kw["trials"], kw["grid"], kw["sort"]) == (7, 20, 3, 128, "cell")
    assert kw["graph"] is True and kw["device"] == "cpu"


# ----------------------------------------------------------------------------- Python API: GaussianSet


def _good(n: int = N) -> dict:
    return {
        "means": torch.rand(n, 3),
        "quats": torch.tensor([[1.0, 0.0, 0.0, 0.0]]).repeat(n, 1),
        "scales": torch.full((n, 3), 0.01),
        "opacities": torch.full((n,), 0.5),
        "sh": torch.zeros(n, 1, 3),
    }


BAD_GAUSSIANS = [
    ("means", torch.rand(N, 2), "shape [6, 2]"),
    ("means", "points.ply", "got a str"),
    ("means", [[0.0, 1.0], [2.0]], "not a rectangular array"),
    ("means", torch.full((N, 3), float("nan")), "NaN"),
    ("means", torch.zeros(N, 3, dtype=torch.bool), "dtype torch.bool"),
    ("quats", torch.zeros(N, 4), "zero or non-finite quaternions"),
    ("quats", torch.ones(N, 3), "shape [6, 3]"),
    ("scales", -torch.ones(N, 3), "torch.exp(log_scales)"),
    ("scales", torch.zeros(N, 3), "outside [1e-18"),
    ("opacities", torch.rand(N - 1), "N = 6"),
    ("opacities", torch.full((N,), 4.0), "torch.sigmoid"),
    ("sh", torch.zeros(N, 2, 3), "K = 2"),
    ("sh", torch.full((N, 1, 3), float("inf")), "NaN or infinite"),
    ("interior", torch.zeros(N + 1, dtype=torch.bool), "shape [7]"),
    ("interior", torch.zeros(N), "not bool"),
    ("labels", torch.full((N,), -1, dtype=torch.int32), "negative labels"),
    ("labels", torch.zeros(N), "integer material labels"),
]


@pytest.mark.parametrize("name,value,needle", BAD_GAUSSIANS, ids=[f"{n}-{k}" for n, _, k in BAD_GAUSSIANS])
def test_gaussian_set_refuses_bad_arrays_by_name(name, value, needle):
    """Rule: a GaussianSet is made only from arrays a renderer and the solver can use (shapes [N, 3], [N, 4],
    [N, 3], [N], [N, K, 3]; finite; σ as the PLY rule; quaternions ≠ 0; opacity in [0, 1]); anything else is
    an ArgumentError (also a TypeError and ValueError) naming the argument."""
    with pytest.raises(ArgumentError) as info:
        GaussianSet(**{**_good(), name: value})
    msg = str(info.value)
    assert msg.startswith(f"GaussianSet: {name} ") and needle in msg and "\n" not in msg, msg
    assert isinstance(info.value, TypeError) and isinstance(info.value, ValueError)


def test_gaussian_set_converts_lists_and_numpy():
    """A list or numpy array of numbers is what a torch user may hand over: it becomes a tensor with the same
    values (float64 numpy stays float64, integers become float32), not a raw torch error."""
    good = _good()
    gs = GaussianSet(**{**good, "means": good["means"].tolist(), "scales": good["scales"].double().numpy()})
    assert torch.is_tensor(gs.means) and torch.equal(gs.means, good["means"])
    assert gs.scales.dtype == torch.float64 and torch.equal(gs.scales.float(), good["scales"])
    ints = GaussianSet(**{**good, "means": [[1, 2, 3]] * N})
    assert ints.means.dtype == torch.float32 and ints.means[0].tolist() == [1.0, 2.0, 3.0]


# ----------------------------------------------------------------------------- Python API: FractureSim


@pytest.fixture(scope="module")
def modules():
    cfg = load_config("bread")
    cfg.frames = 1
    return FractureSim(cfg, device="cpu"), FractureSim(cfg, device="cpu", differentiable=True)


FORWARD_BAD = [
    ("plain", {"means": torch.rand(N, 2)}, "means has shape [6, 2]"),
    ("plain", {"means": [[0.1, 0.2]] * N}, "means has shape [6, 2]"),
    ("plain", {"opacities": torch.rand(N + 2)}, "opacities has shape [8]"),
    ("plain", {"interior": torch.zeros(N - 1, dtype=torch.bool)}, "interior has shape [5]"),
    ("plain", {"quats": torch.zeros(N, 4)}, "quats has 6 row(s) with zero"),
    ("plain", {"scales": -torch.full((N, 3), 0.01)}, "scales has 6 row(s)"),
    ("plain", {"scales": None}, "scales is missing"),
    ("plain", {"covars": torch.eye(3).repeat(N, 1, 1)}, "covars and quats/scales were both given"),
    ("plain", {"quats": None, "scales": None, "covars": -torch.eye(3).repeat(N, 1, 1)}, "covars has negative"),
    ("plain", {"quats": None, "scales": None, "covars": torch.rand(N, 3, 3) + 2.0}, "not symmetric"),
    ("diff", {"E": torch.tensor(-5.0)}, "E = -5.0 must be a positive finite number"),
    ("diff", {"E": torch.zeros(N)}, "E = 0.0 must be a positive"),
    ("diff", {"nu": 0.5}, "nu = 0.5 is outside [0.0, 0.5)"),
    ("diff", {"nu": -1.0}, "nu = -1.0 is outside"),
    ("diff", {"nu": torch.full((N,), 0.7)}, "nu = 0.7 is outside"),
    ("diff", {"density": float("nan")}, "density = nan must be a positive finite number"),
    ("diff", {"density": torch.ones(N + 1)}, "density has shape [7]"),
    ("diff", {"velocity": torch.zeros(N, 2)}, "velocity has shape [6, 2]"),
    ("diff", {"velocity": [0.0, float("inf"), 0.0]}, "velocity has NaN or infinite"),
]


@pytest.mark.parametrize("mode,change,needle", FORWARD_BAD, ids=[f"{m}-{n}" for m, _, n in FORWARD_BAD])
def test_fracture_sim_forward_refuses_bad_arguments_by_name(mode, change, needle, modules):
    """Rule: FractureSim.forward checks every argument where it enters — shapes against N, values (the
    material ranges are the config's: E > 0, 0 ≤ ν < 0.5, ρ > 0, all finite) — and raises one ArgumentError
    sentence naming the argument, before any simulation starts."""
    plain, diff = modules
    kwargs = {**_good(), **change}
    with pytest.raises(ArgumentError) as info:
        (plain if mode == "plain" else diff)(**kwargs)
    msg = str(info.value)
    assert msg.startswith("FractureSim.forward: ") and needle in msg and "\n" not in msg, msg


def test_material_arguments_follow_the_config_ranges():
    """The differentiable mode's E, ν and ρ are held to the config's own rules (io/config/validate, one
    statement of the ranges): ν = 0 and 0.499 pass, 0.5 does not (the bound is open); tensors keep autograd."""
    E = torch.tensor(2e6, dtype=torch.float64, requires_grad=True)
    assert _material_argument("E", E, N) is E
    assert _material_argument("nu", 0.0, N).item() == 0.0 and _material_argument("nu", [0.499] * N, N).shape == (N,)
    with pytest.raises(ArgumentError, match=r"nu = 0\.5 is outside \[0\.0, 0\.5\)"):
        _material_argument("nu", torch.tensor([0.3, 0.5]), 2)


def test_physical_arguments_without_the_differentiable_mode_are_refused(modules):
    """E, ν, ρ and velocity act only in the differentiable mode: given to the plain module they would be
    ignored, so the call is refused naming them."""
    plain, _ = modules
    with pytest.raises(SimulationError, match=r"FractureSim.forward: E, velocity would be ignored"):
        plain(**_good(), E=1e6, velocity=torch.zeros(3))


def test_fracture_sim_constructor_refuses_bad_arguments():
    """FractureSim(cfg, variant, device): a config of another type, an unknown variant or a device torch does not
    know is one ArgumentError naming it (not an AttributeError or a late Warp error)."""
    for kwargs, needle in (
        ({"cfg": 42}, "cfg must be a SceneConfig, got int"),
        ({"cfg": "bread", "variant": "fulll"}, "variant 'fulll' is unknown"),
        ({"cfg": "bread", "device": "gpu"}, "device 'gpu' is not a torch device"),
    ):
        with pytest.raises(ArgumentError, match=needle):
            FractureSim(**kwargs)
    with pytest.raises(ArgumentError, match="FractureSim.frames: gs is a dict"):
        next(FractureSim("bread").frames({}))


def test_gaussians_from_tensors_accepts_the_documented_variants():
    """[N, 3] colours as degree-0 SH, [N, 1] opacities and covariances instead of quats/scales are accepted:
    Σ = R S² Rᵀ comes back from the factored set."""
    g = _good()
    rot = torch.linalg.qr(torch.randn(N, 3, 3, dtype=torch.float64))[0]
    s = torch.rand(N, 3, dtype=torch.float64) + 0.1
    cov = rot @ torch.diag_embed(s**2) @ rot.transpose(1, 2)
    gs = gaussians_from_tensors(g["means"], g["opacities"][:, None], torch.zeros(N, 3), covars=cov.float())
    assert gs.sh.shape == (N, 1, 3) and gs.opacities.shape == (N,)
    torch.testing.assert_close(gs.covariances().double(), cov, rtol=1e-4, atol=1e-6)


# ----------------------------------------------------------------------------- path arguments


def _gs() -> GaussianSet:
    return GaussianSet(**_good())


PATH_CALLS = {
    "load_ply": lambda p: load_ply(p),
    "load_ply_lenient": lambda p: load_ply_lenient(p),
    "read_gaussians": lambda p: read_gaussians(p),
    "detect_format": lambda p: detect_format(p),
    "is_splat_file": lambda p: is_splat_file(p),
    "save_ply": lambda p: save_ply(_gs(), p),
    "write_gaussians": lambda p: write_gaussians(_gs(), p, "splat"),
}


@pytest.mark.parametrize("value", [123, None, 1.5, ["scene.ply"], ""], ids=["int", "None", "float", "list", "empty"])
@pytest.mark.parametrize("func", sorted(PATH_CALLS))
def test_path_arguments_must_be_paths(func, value):
    """Rule: a function that takes a file path refuses anything else (load_ply(123) was a bare TypeError from
    os.fspath) with an ArgumentError naming the function and its `path` argument."""
    with pytest.raises(ArgumentError) as info:
        PATH_CALLS[func](value)
    assert str(info.value).startswith(f"{func}: path ") and isinstance(info.value, TypeError), str(info.value)


def test_writers_refuse_a_non_gaussian_set_and_report_unwritable_paths(tmp_path):
    """save_ply / write_gaussians take a GaussianSet (a dict is named, not an AttributeError); a folder that
    does not exist is one OutputError sentence naming the file, not a FileNotFoundError traceback."""
    with pytest.raises(ArgumentError, match="save_ply: gs must be a GaussianSet, got dict"):
        save_ply({}, tmp_path / "x.ply")
    with pytest.raises(ArgumentError, match="write_gaussians: gs must be a GaussianSet, got str"):
        write_gaussians("gs", tmp_path / "x.spz", "spz")
    for write in (lambda p: save_ply(_gs(), p), lambda p: write_gaussians(_gs(), p.with_suffix(".splat"), "splat")):
        with pytest.raises(FractureGSError, match="cannot write the file"):
            write(tmp_path / "missing" / "x.ply")
        assert not (tmp_path / "missing").exists()
    with pytest.raises(ArgumentError, match="load_ply: device 'gpu'"):
        load_ply(SPZ, device="gpu")


# ----------------------------------------------------------------------------- Ctrl-C


def test_importing_the_cli_loads_neither_torch_nor_warp():
    """The console entry point's module imports nothing heavy at its top, so the imports of torch and Warp
    happen inside main()'s KeyboardInterrupt handler (a fresh interpreter: nothing imported before)."""
    code = (
        "import sys, fracture_gs, fracture_gs.cli; print([m for m in ('torch', 'warp', 'numpy') if m in sys.modules])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr


def test_an_interrupt_turned_into_another_error_still_exits_130(monkeypatch, capsys, request):
    """A SIGINT that arrives inside a C extension's import comes out as an ImportError (numpy's did), and one
    inside an import lock's callback is dropped by Python: main() records the signal, so both end as
    'interrupted' with 130, and the previous SIGINT handler is back afterwards. The test starts from Python's own
    handler, as a process run from a terminal does (an earlier test in the session may have left another)."""
    outer = signal.signal(signal.SIGINT, signal.default_int_handler)
    request.addfinalizer(lambda: signal.signal(signal.SIGINT, outer))
    before = signal.getsignal(signal.SIGINT)

    def converted():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)  # the handler runs here
        except KeyboardInterrupt as exc:
            raise ImportError("PyCapsule_Import could not import module 'datetime'") from exc

    def dropped():
        try:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        except KeyboardInterrupt:
            pass  # "Exception ignored in ..."
        return {"info": lambda args: 0}

    for commands in (converted, dropped):
        monkeypatch.setattr(cli, "_commands", commands)
        assert cli.main(["info"]) == 130
        err = capsys.readouterr().err
        assert "fracture-gs: interrupted; nothing was written." in err and "Traceback" not in err
        assert signal.getsignal(signal.SIGINT) is before


def _wait_until_mapped(proc, library: str, timeout: float = 60.0) -> None:
    """Return once the child process has mapped a shared library whose path contains `library`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if library in Path(f"/proc/{proc.pid}/maps").read_text():
                return
        except OSError:
            pass
        time.sleep(0.005)
    raise AssertionError(f"the child never loaded {library} (exit {proc.poll()})")


@pytest.mark.slow
@pytest.mark.parametrize("entry", ["-m", "script"])
def test_ctrl_c_while_importing_exits_130(entry, tmp_path):
    """SIGINT as torch starts loading and 0.25 and 0.5 s later (while torch and Warp load): exit 130, the one-line
    'interrupted' message, no traceback; for `python -m fracture_gs.cli` and the console script's code
    (`from fracture_gs.cli import main; sys.exit(main())`). The clock starts when the child maps torch's library
    (inside main(), after its handler is installed), not at spawn: on a loaded machine the interpreter's own
    start-up, before any package code runs, can outlast a fixed delay (DESIGN.md, Ctrl-C)."""
    launch = (
        ["-m", "fracture_gs.cli"]
        if entry == "-m"
        else ["-c", "import sys; from fracture_gs.cli import main; sys.exit(main())"]
    )
    for delay in (0.0, 0.25, 0.5):
        proc = subprocess.Popen(
            [
                sys.executable,
                *launch,
                "render-sim",
                "bread",
                "--frames",
                "1",
                "--device",
                "cpu",
                "--out",
                str(tmp_path),
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=ROOT,
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
        )
        _wait_until_mapped(proc, "libtorch")
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == 130 and "Traceback" not in err, (delay, proc.returncode, err[-2000:])
        assert "fracture-gs: interrupted;" in err, err
