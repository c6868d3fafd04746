"""`fracture-gs` CLI: help, info, validate and one-line user errors (in-process and via subprocess)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.render_sim import RunSummary
from fracture_gs.render_sim import job as render_job

REPO = Path(__file__).resolve().parent.parent
COMMANDS = ["render-sim", "bench", "figures", "sweep", "info", "validate"]


def start(*args: str) -> subprocess.Popen:
    """Start `python -m fracture_gs.cli ARGS` in a fresh interpreter (several run concurrently)."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    env.pop("FRACTURE_GS_DEBUG", None)
    return subprocess.Popen(
        [sys.executable, "-m", "fracture_gs.cli", *args],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def finish(proc: subprocess.Popen) -> tuple[int, str, str]:
    out, err = proc.communicate(timeout=120)
    return proc.returncode, out, err


def assert_one_line_error(code: int, err: str) -> None:
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("fracture-gs: error: "), err
    assert "Traceback" not in err


# ---------------------------------------------------------------- subprocess (the real entry point)


@pytest.mark.slow
def test_subprocess_validate_info_and_error(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[sim]\ngravty = [0, 0, -9.8]\n")
    procs = [start("validate", "configs/bread.toml"), start("validate", str(bad)), start("info")]
    (code, out, err), (bad_code, _, bad_err), (info_code, info_out, info_err) = map(finish, procs)
    assert code == 0, err
    assert "ok: config is valid" in out and "stress" in out
    assert_one_line_error(bad_code, bad_err)
    assert "did you mean 'gravity'" in bad_err
    assert info_code == 0, info_err
    assert "torch" in info_out and "warp" in info_out and "renderer" in info_out


# ---------------------------------------------------------------- in-process


@pytest.mark.parametrize("command", COMMANDS)
def test_subcommand_help_has_examples(command, capsys):
    assert cli.main([command, "--help"]) == 0
    text = capsys.readouterr().out
    assert "examples:" in text and f"fracture-gs {command}" in text


def test_main_help(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "examples:" in out and "render-sim" in out and "bread" in out


def test_no_command_prints_help(capsys):
    assert cli.main([]) == 0
    assert "COMMAND" in capsys.readouterr().out


def test_validate_builtin_name_and_dump(capsys):
    assert cli.main(["validate", "exp_table5_bread_vlm", "--dump"]) == 0
    out = capsys.readouterr().out
    assert "ok: config is valid" in out and "sigma_R = 55.0" in out and "[[sim.boundaries]]" in out


def test_info_in_process(capsys):
    assert cli.main(["info"]) == 0
    out = capsys.readouterr().out
    for word in ("python", "torch", "warp", "gsplat", "kernel cache", "renderer"):
        assert word in out


BAD_CALLS = [
    (["validate", "does/not/exist.toml"], "no such config file"),
    (["validate", "INVALID"], "unknown key"),
    (["validate", "INVALID_VALUE"], "material.nu"),
    (["render-sim", "bread", "--device", "gpu"], "not a device"),
    (["render-sim", "bread", "--device", "cuda:7"], "cuda:7"),
    (["render-sim", "bread", "--resolution", "640by480"], "must be WxH with positive integers, got 640by480"),
    (["render-sim", "bread", "--resolution", "1x480"], "too small"),
    (["render-sim", "bread", "--variants", "baseline,fulll"], "did you mean 'full'"),
    (["render-sim", "bread", "--preset", "huge"], "--preset"),
    (["render-sim", "bread", "--frames", "zero"], "--frames"),
    (["render-sim", "bread", "--bogus"], "unrecognized arguments"),
    (["figures", "--device", "tpu"], "not a device"),
    (["bench", "--steps", "0", "--device", "cpu"], "must be at least 1"),
    (["bench", "--accuracy", "--cases", "bar,nope", "--device", "cpu"], "--cases nope unknown"),
    (["figures", "--only", "ficus,nope", "--device", "cpu"], "--only nope unknown"),
    (["figures", "--protocol", "fast"], "invalid choice"),
    (["render-sim", "scene.ply"], "no such PLY file"),
    (["render-sim", "scene.spz"], "no such .spz file"),
    (["render-sim", "bread", "--export-format", "spz"], "--export-format spz needs --export-ply"),
    (["render-sim", "bread", "--export-ply", "2", "--export-format", "gltf"], "invalid choice"),
    (["init", "bread"], "init takes a captured scene"),
]


@pytest.mark.parametrize("argv,needle", BAD_CALLS, ids=[" ".join(a) for a, _ in BAD_CALLS])
def test_user_errors_are_one_line(argv, needle, tmp_path, capsys):
    invalid = tmp_path / "invalid.toml"
    invalid.write_text('extends = "bread"\n[sim]\ngravty = [0, 0, 0]\n')
    invalid_value = tmp_path / "invalid_value.toml"
    invalid_value.write_text('extends = "bread"\n[material]\nnu = 0.5\n')
    argv = [{"INVALID": str(invalid), "INVALID_VALUE": str(invalid_value)}.get(a, a) for a in argv]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert_one_line_error(code, err)
    assert needle in err


def test_cuda_request_without_cuda(monkeypatch, capsys):
    monkeypatch.setattr(cli.devices, "_cuda_devices", lambda: (False, 0, "torch.cuda.is_available() is False"))
    assert_one_line_error(cli.main(["render-sim", "bread", "--device", "cuda"]), capsys.readouterr().err)


def test_resolve_device(monkeypatch):
    monkeypatch.setattr(cli.devices, "_cuda_devices", lambda: (True, 2, "ok"))
    assert (cli.resolve_device("auto"), cli.resolve_device("cuda"), cli.resolve_device("cuda:1")) == (
        "cuda:0",
        "cuda:0",
        "cuda:1",
    )
    monkeypatch.setattr(cli.devices, "_cuda_devices", lambda: (False, 0, "no"))
    assert (cli.resolve_device("auto"), cli.resolve_device("CPU")) == ("cpu", "cpu")


def test_render_sim_dispatches_to_runner(monkeypatch, tmp_path, capsys):
    calls = {}

    def fake_run(cfg, variants, device, out_dir, profile=False, stop=None, schedule="in_turn"):
        calls.update(cfg=cfg, variants=variants, device=device, out_dir=out_dir, profile=profile, stop=stop)
        calls.update(schedule=schedule)
        return RunSummary("bread", "bread", "paper", device, 10, [], 3, 0.01, out_dir=str(out_dir / "compare.mp4"))

    monkeypatch.setattr(runner, "run_render_sim", fake_run)
    code = cli.main(
        [
            "render-sim",
            "bread",
            "--variants",
            "baseline,full",
            "--frames",
            "3",
            "--resolution",
            "64x48",
            "--preset",
            "paper",
            "--device",
            "cpu",
            "--out",
            str(tmp_path),
        ]
    )
    assert code == 0, capsys.readouterr().err
    assert calls["variants"] == ["baseline", "full"] and calls["device"] == "cpu" and calls["out_dir"] == tmp_path
    assert calls["cfg"].frames == 3 and calls["cfg"].sim.grid_shape == (128, 128, 128)
    assert isinstance(calls["stop"], threading.Event) and not calls["stop"].is_set()  # Ctrl-C would set it
    assert calls["schedule"] == "auto"  # the CLI lets the job choose in turn or processes once the scene is known
    assert "compare.mp4" in capsys.readouterr().out


def test_keyboard_interrupt_reports_partial_outputs(monkeypatch, tmp_path, capsys):
    def interrupted(cfg, variants, device, out_dir, profile=False, stop=None, schedule="in_turn"):
        (out_dir / "config.toml").write_text("")  # something written before the Ctrl-C
        raise KeyboardInterrupt

    monkeypatch.setattr(runner, "run_render_sim", interrupted)
    assert cli.main(["render-sim", "recontact", "--device", "cpu", "--out", str(tmp_path)]) == 130
    assert f"partial outputs are in {tmp_path}" in capsys.readouterr().err


def test_bugs_keep_their_traceback(monkeypatch):
    def broken(cfg, variants, device, out_dir, profile=False, stop=None, schedule="in_turn"):
        raise RuntimeError("bug")

    monkeypatch.setattr(runner, "run_render_sim", broken)
    with pytest.raises(RuntimeError):
        cli.main(["render-sim", "recontact", "--device", "cpu"])


def test_render_sim_without_video_encoder_stops_before_the_scene(tmp_path, capsys, monkeypatch):
    """render-sim checks for imageio-ffmpeg before it prepares (or simulates) anything: one error line naming
    the pip command and exit code 2, with no scene built."""
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # `import imageio_ffmpeg` now raises ImportError

    def never(*args, **kwargs):
        raise AssertionError("the scene was prepared before the encoder check")

    monkeypatch.setattr(render_job, "prepare_scene", never)
    code = cli.main(["render-sim", "ficus", "--frames", "2", "--device", "cpu", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2
    assert "pip install imageio-ffmpeg" in err and "Traceback" not in err


def test_info_reports_the_video_encoder(capsys, monkeypatch):
    """`info` names the MP4 encoder render-sim will use, and without imageio-ffmpeg the sentence render-sim
    would stop with (info itself still succeeds)."""
    assert cli.main(["info"]) == 0
    assert "imageio-ffmpeg" in next(line for line in capsys.readouterr().out.splitlines() if line.startswith("video"))
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    assert cli.main(["info"]) == 0
    line = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("video"))
    assert "unavailable" in line and "pip install imageio-ffmpeg" in line


def test_a_bare_value_error_is_reported_as_a_bug_not_as_bad_input(monkeypatch, capsys):
    """Every bad input is refused as a package error where it enters (exit 2, naming the key); a ValueError from
    elsewhere is a bug in fracture-gs, so it must not pose as the user's mistake: exit 1, one line that says so
    and how to get the traceback, no traceback printed."""
    import fracture_gs.cli as cli

    def broken(args):
        raise ValueError("invalid literal for int() with base 10: 'x'")

    monkeypatch.setattr(cli, "_commands", lambda: {"info": broken})
    assert cli.main(["info"]) == 1
    err = capsys.readouterr().err
    assert "internal error: ValueError" in err and "FRACTURE_GS_DEBUG=1" in err and "Traceback" not in err
    monkeypatch.setenv("FRACTURE_GS_DEBUG", "1")
    with pytest.raises(ValueError):
        cli.main(["info"])
