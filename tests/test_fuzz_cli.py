"""Property: any argument list given to `fracture-gs` ends with an exit code (0 ok, 1 a variant failed, 2 a
user error with exactly one `fracture-gs: error:` line on stderr) — `main` never raises, never prints a
traceback. Argument lists mix every subcommand's flags with valid values, known-bad values (each must be
refused: no silent acceptance), random unicode tokens, unknown flags and odd --out targets. The heavy
work (simulation, benchmarks, figures) is replaced by a recorder that checks what it receives: a
validated config, an existing output folder, a resolved device."""

from __future__ import annotations

import pytest
from fuzzutil import Tally, fuzz_settings, run_cli
from hypothesis import given
from hypothesis import strategies as st

from fracture_gs import cli
from fracture_gs.io.config import validate
from fracture_gs.render_sim import RunSummary

TEXT = st.text(st.characters(exclude_categories=["Cs"], exclude_characters="\x00"), max_size=10)

# flag -> (valid values, known-bad values); None = a switch without a value
FLAGS = {
    "render-sim": {
        "--variants": (["baseline,full", "full", "baseline"], ["nope", "", "full,full", "baseline,fulll", "full,"]),
        "--preset": (["small", "paper"], ["huge", ""]),
        "--frames": (["1", "2"], ["0", "-1", "x", "1.5"]),
        "--particles": (["300", "500"], ["0", "-5", "many"]),
        "--resolution": (["64x48", "32X32", "16×16"], ["0x0", "²x²", "9000x10", "64", "axb"]),
        "--load": (["pull", "drop", "impact", "none"], ["throw"]),
        "--devices": (["cpu"], ["gpu", "cuda:9", ",", "cpu,cpu", "cpu,auto"]),
        "--export-ply": (["1", "5"], ["0", "-2"]),
        "--profile": (None, None),
        "--device": (["cpu", "auto", "CPU"], ["gpu", "", "cuda:99", "cuda:x"]),  # cuda:99: no machine has it
    },
    "bench": {
        "--particles": (["1000"], ["0", "-1", str(10**10)]),
        "--steps": (["1", "3"], ["0", "x"]),
        "--warmup": (["1"], ["0"]),
        "--trials": (["1"], ["0"]),
        "--grid": (["16", "32"], ["0", "-3", "2", "100000"]),  # round four: 8 to 256 nodes per axis
        "--sort": (["interleaved", "cell"], ["random"]),
        "--no-graph": (None, None),
        "--device": (["cpu", "auto"], ["gpu", ""]),
    },
    "figures": {
        "--protocol": (["quick", "paper"], ["fast"]),
        "--only": (["ficus", "bread,bench"], ["nope", "ficus,nope"]),
        "--reuse": (None, None),
        "--backend": (["torch", "auto"], ["opengl"]),
        "--device": (["cpu"], ["tpu"]),
    },
    "validate": {"--dump": (None, None)},
    "info": {},
    "init": {"--load": (["drop"], ["throw"]), "--force": (None, None)},
}
POSITIONAL = {
    "render-sim": (["bread", "ficus", "plane_drop"], ["nope", "", "scene.ply", "/", "."]),
    "validate": (["bread", "recontact", "exp_table3_bread"], ["nope", "", "..", "x.ply"]),
    "init": ([], ["missing.ply", "bread", ""]),
    "bench": ([], []),
    "figures": ([], []),
    "info": ([], []),
}
BAD_OUT = ["", "/dev/null", "A_FILE", "A_FILE/sub", "n" * 300]  # a name over 255 bytes: round four


@st.composite
def argv_case(draw):
    """(argv, planted): planted names the known-bad token if one was put in (the call must then fail)."""
    cmd = draw(st.sampled_from([*FLAGS] * 4 + ["render", "--bogus", ""]))
    argv, planted = ([cmd] if cmd else []), None
    if cmd not in FLAGS:
        return argv + draw(st.lists(TEXT, max_size=3)), "unknown command" if cmd else None
    good, bad = POSITIONAL[cmd]
    if good or bad:
        if bad and (not good or draw(st.integers(0, 4)) == 0):
            argv.append(draw(st.sampled_from(bad)))
            planted = f"positional {argv[-1]!r}"
        else:
            argv.append(draw(st.sampled_from(good)))
    flags = draw(st.lists(st.sampled_from(sorted(FLAGS[cmd])), max_size=4, unique=True)) if FLAGS[cmd] else []
    for flag in flags:
        valid, invalid = FLAGS[cmd][flag]
        if valid is None:
            argv.append(flag)
        elif planted is None and draw(st.integers(0, 3)) == 0:
            argv += [flag, draw(st.sampled_from(invalid))]
            planted = f"{flag} {argv[-1]!r}"
        else:
            argv += [flag, draw(st.sampled_from(valid))]
    if cmd not in ("validate", "info") and draw(st.booleans()):
        if planted is None and draw(st.booleans()):
            argv += ["--out", draw(st.sampled_from(BAD_OUT))]
            planted = f"--out {argv[-1]!r}"
        else:
            argv += ["--out", "outputs/" + draw(st.sampled_from(["a", "b c", "é"]))]
    if draw(st.integers(0, 5)) == 0:  # noise: a random token somewhere (outcome not planted: either is fine)
        argv.insert(draw(st.integers(0, len(argv))), draw(st.one_of(TEXT, st.sampled_from(["--bogus", "-x", "--"]))))
        planted = None
    return argv, planted


class Recorder:
    """Stands in for the heavy entry points; checks what the CLI hands over."""

    def __init__(self):
        self.calls = 0

    def render_sim(self, cfg, variants, device, out_dir, **kw):
        validate(cfg, "dispatched config")
        assert device in ("cpu",) and out_dir.is_dir() and set(variants) == set(cfg.variants)
        self.calls += 1
        return RunSummary(
            cfg.name,
            cfg.scene,
            cfg.preset,
            device,
            1,
            [],
            cfg.frames,
            cfg.frame_dt,
            [{"variant": v, "status": "ok"} for v in variants],
        )

    def bench(self, device=None, out_dir=None, **kw):
        assert device == "cpu" and out_dir.is_dir()
        self.calls += 1
        return {"ok": True}

    def figures(self, device, out_dir, **kw):
        assert device == "cpu" and out_dir.is_dir()
        self.calls += 1
        return {"ok": True}


@pytest.mark.slow
@pytest.mark.usefixtures("one_thread")
def test_fuzz_cli(tmp_path, monkeypatch, capsys):
    import fracture_gs.paper.bench as bench
    import fracture_gs.paper.figures as figures
    import fracture_gs.render_sim as runner

    rec = Recorder()
    monkeypatch.setattr(runner, "run_render_sim", rec.render_sim)
    monkeypatch.setattr(bench, "run_bench", rec.bench)
    monkeypatch.setattr(figures, "run_figures", rec.figures)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "A_FILE").write_text("in the way")
    monkeypatch.delenv("FRACTURE_GS_DEBUG", raising=False)
    tally = Tally("CLI")

    @fuzz_settings(800)
    @given(argv_case())
    def prop(case):
        argv, planted = case
        category = (argv[0] if argv and argv[0] in FLAGS else "other") + (" planted" if planted else "")
        code, err, _ = run_cli(cli.main, argv, capsys, tally, category)
        if code == 2:
            tally.add(category, "our error")
        elif planted and "--help" not in argv and "-h" not in argv:
            tally.add(category, "silent acceptance")
            raise AssertionError(f"{argv} was accepted (exit {code}) though {planted} is invalid")
        else:
            assert code == 0, (argv, code, err)
            tally.add(category, "clean load")

    prop()
    tally.report(capsys)
    assert tally.total() >= 800 and tally.total("traceback") == 0 and tally.total("silent acceptance") == 0
    assert rec.calls > 20 and tally.total("our error") > 50
