"""Property: the Python API and the CLI's flag combinations either accept an input that is valid — and then
hand it on unchanged — or refuse it with one `fracture_gs.errors` sentence naming the argument or flag; never
another exception, never a silent acceptance. Each suite states validity independently of the code under test
(which fields were spoiled, the documented material ranges, which flags act on which scene) and compares.

- Gaussian arrays (`GaussianSet(...)` and `FractureSim.forward`'s conversion): every field drawn as a valid
  tensor, a list, a float64 numpy array or an integer tensor (all to be accepted), or spoiled: a wrong shape,
  a non-numeric type, a bool or complex dtype, a ragged list, NaN / inf, or a field's own invalid value
  (σ ≤ 0, a zero quaternion, an opacity outside [0, 1], a negative label).
- E, ν, ρ and velocity of the differentiable forward: scalars, lists and tensors of any shape and value.
- render-sim, bench and figures flags in arbitrary combinations on a built-in scene, a capture and captured
  configs whose fit is off, whose resolution is fixed or which carry their own load; the runners replaced by
  recorders."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
from fuzzutil import Tally, fuzz_settings, ok_summary, run_cli
from hypothesis import given
from hypothesis import strategies as st

from fracture_gs import cli
from fracture_gs import render_sim as runner
from fracture_gs.errors import ArgumentError
from fracture_gs.io import GaussianSet
from fracture_gs.module import FORWARD, _material_argument, _velocity_argument, gaussians_from_tensors

FIELDS = ("means", "quats", "scales", "opacities", "sh", "interior", "labels")
WIDTH = {"means": (3,), "quats": (4,), "scales": (3,), "opacities": (), "sh": (1, 3), "interior": (), "labels": ()}
SPOILS = ("shape", "type", "dtype", "ragged", "nonfinite", "invalid")


def _valid(name: str, n: int, rng: np.random.Generator) -> np.ndarray:
    """Values a field may hold (float64 numpy; the representation is chosen afterwards)."""
    shape = (n, *WIDTH[name])
    if name == "quats":
        q = rng.normal(size=shape)
        q[np.linalg.norm(q, axis=-1) < 1e-3] = [1, 0, 0, 0]
        return q
    if name == "scales":
        return rng.uniform(1e-4, 1.0, size=shape)
    if name == "opacities":
        return rng.uniform(0.0, 1.0, size=shape)
    if name == "interior":
        return rng.integers(0, 2, size=shape).astype(bool)
    if name == "labels":
        return rng.integers(0, 5, size=shape)
    return rng.normal(size=shape)


def _invalid_value(name: str, a: np.ndarray, row: int, draw) -> np.ndarray:
    """The field's own kind of wrong value in one row (a must have that row)."""
    a = a.astype(np.float64).copy()
    if name == "quats":
        a[row] = 0.0
    elif name == "scales":
        a[row, draw(st.integers(0, 2))] = draw(st.sampled_from([0.0, -1e-3, -1.0, 1e19]))
    elif name == "opacities":
        a[row] = draw(st.sampled_from([-0.01, 1.5, 80.0]))
    elif name == "labels":
        a[row] = -draw(st.integers(1, 9))
    return a


@st.composite
def gaussian_case(draw):
    """(arrays, spoiled fields, target): target "set" (GaussianSet) or "forward" (FractureSim's conversion)."""
    n = draw(st.integers(0, 5))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    target = draw(st.sampled_from(["set", "forward"]))
    arrays, spoiled = {}, set()
    for name in FIELDS:
        if name in ("interior", "labels") and draw(st.booleans()):
            arrays[name] = None  # optional: defaults fill in
            continue
        a = _valid(name, n, rng)
        spoil = draw(st.sampled_from(SPOILS + ("",) * 8)) if draw(st.integers(0, 2)) == 0 else ""
        if spoil in ("nonfinite", "invalid") and (n == 0 or name == "interior"):
            spoil = ""
        if spoil == "invalid" and name in ("means", "sh"):
            spoil = "nonfinite"
        if spoil == "nonfinite" and name == "labels":
            spoil = "invalid"
        if spoil == "shape":
            dims = draw(st.lists(st.integers(0, 4), max_size=3))
            allowed = [(n, *WIDTH[name])]
            if target == "forward":
                allowed += {"opacities": [(n, 1)], "sh": [(n, 3)]}.get(name, [])
            if tuple(dims) in allowed or (name == "means" and len(dims) == 2 and dims[1] == 3):
                spoil = ""  # a shape that is valid after all (means [M, 3] only changes N)
            else:
                arrays[name] = torch.zeros(dims, dtype=torch.bool if name == "interior" else torch.float32)
        if spoil == "type":
            arrays[name] = draw(st.sampled_from(["scene.ply", {"x": 1}, object(), {1, 2}, b"\x00"]))
        elif spoil == "dtype":
            arrays[name] = torch.zeros(
                (n, *WIDTH[name]), dtype=torch.complex64 if name != "interior" else torch.float32
            )
        elif spoil == "ragged":
            arrays[name] = [[0.0] * (i + 1) for i in range(max(n, 2))]
        elif spoil == "nonfinite":
            a = a.astype(np.float64)
            a.reshape(n, -1)[draw(st.integers(0, n - 1)), 0] = draw(st.sampled_from([math.nan, math.inf, -math.inf]))
            arrays[name] = torch.from_numpy(a).float()
        elif spoil == "invalid":
            arrays[name] = torch.from_numpy(_invalid_value(name, a, draw(st.integers(0, n - 1)), draw))
            if name == "labels":
                arrays[name] = arrays[name].to(torch.int32)
        elif spoil == "":
            rep = draw(st.sampled_from(["tensor", "list", "numpy", "int"] if n else ["tensor", "numpy", "int"]))
            if name in ("interior", "labels"):
                arrays[name] = torch.from_numpy(a) if name == "interior" else torch.from_numpy(a).to(torch.int32)
            elif rep == "list":
                arrays[name] = a.tolist()
            elif rep == "numpy":
                arrays[name] = a
            elif rep == "int":
                ints = {"quats": np.tile([1, 0, 0, 0], (n, 1)), "scales": np.ones((n, 3)), "opacities": np.ones(n)}
                arrays[name] = torch.from_numpy(ints.get(name, np.rint(a)).astype(np.int64).reshape(a.shape))
            else:
                arrays[name] = torch.from_numpy(a).float()
            if target == "forward" and name == "opacities" and draw(st.booleans()) and rep == "tensor":
                arrays[name] = arrays[name].reshape(n, 1)
        if spoil:
            spoiled.add(name)
    return arrays, spoiled, target


def _as_float(value) -> torch.Tensor:
    return torch.as_tensor(np.asarray(value, dtype=np.float64) if not torch.is_tensor(value) else value).double()


def test_fuzz_gaussian_arrays(capsys):
    tally = Tally("Python API: Gaussian arrays")

    @fuzz_settings(400)
    @given(gaussian_case())
    def prop(case):
        arrays, spoiled, target = case
        category = f"{target} {'spoiled ' + '+'.join(sorted(spoiled)) if spoiled else 'valid'}"
        where = "GaussianSet" if target == "set" else FORWARD
        try:
            if target == "set":
                gs = GaussianSet(**arrays)
            else:
                a = dict(arrays)
                gs = gaussians_from_tensors(a.pop("means"), a.pop("opacities"), a.pop("sh"), **a)
        except ArgumentError as exc:
            msg = str(exc)
            assert "\n" not in msg and msg.startswith(f"{where}: "), msg
            named = msg[len(where) + 2 :].split(" ")[0]
            if not spoiled:
                tally.add(category, "false rejection")
                raise AssertionError(f"valid arrays refused: {msg}") from None
            assert named in spoiled, (msg, spoiled)
            tally.add(category, "our error")
            return
        except Exception:
            tally.add(category, "traceback")
            raise
        if spoiled:
            tally.add(category, "silent acceptance")
            raise AssertionError(f"{sorted(spoiled)} spoiled but accepted")
        tally.add(category, "clean load")
        for name in ("means", "quats", "scales", "sh", "opacities"):  # a list of floats becomes float32
            got = getattr(gs, name).double()
            torch.testing.assert_close(got, _as_float(arrays[name]).reshape(got.shape), rtol=1e-6, atol=0)

    prop()
    tally.report(capsys)
    assert tally.total("traceback") == tally.total("silent acceptance") == tally.total("false rejection") == 0
    assert tally.total("clean load") > 40 and tally.total("our error") > 100


# ----------------------------------------------------------------------------- material arguments

NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=32),
    st.sampled_from([0.0, -0.0, 0.5, 0.4999, -1.0, 1e-30, 1e30, 2e6, 200.0, 0.3]),
)


def _material_ok(name: str, values: list[float]) -> bool:
    """The documented ranges (README / config.py docstrings): E > 0, ρ > 0, 0 ≤ ν < 0.5, all finite."""
    if not all(math.isfinite(v) for v in values):
        return False
    if name == "nu":
        return all(0.0 <= v < 0.5 for v in values)
    return all(v > 0 for v in values)


@st.composite
def material_case(draw):
    n = draw(st.integers(1, 4))
    name = draw(st.sampled_from(["E", "nu", "density", "velocity"]))
    kind = draw(st.sampled_from(["scalar", "list", "tensor", "tensor64", "wrong-shape", "string", "bool"]))
    if name == "velocity":
        shape = draw(st.sampled_from([(3,), (n, 3), (n, 2), (2,), (), (n, 3, 1), (n + 1, 3)]))
    else:
        shape = draw(st.sampled_from([(), (n,)] + ([(n + 1,), (n, 1), (2, n)] if kind == "wrong-shape" else [])))
    count = int(np.prod(shape)) if shape else 1
    values = draw(st.lists(NUMBERS, min_size=count, max_size=count))
    if kind == "string":
        return name, n, "stiff", "type"
    if kind == "bool":
        return name, n, torch.zeros(shape, dtype=torch.bool), "type"
    if kind == "scalar" and not shape:
        value = values[0]
    elif kind == "list":
        value = np.array(values).reshape(shape).tolist()
    else:
        value = torch.tensor(values, dtype=torch.float64 if kind == "tensor64" else torch.float32).reshape(shape)
    return name, n, value, None


def test_fuzz_material_arguments(capsys):
    tally = Tally("Python API: E, nu, density, velocity")

    @fuzz_settings(400)
    @given(material_case())
    def prop(case):
        name, n, value, fault = case
        t = None if fault else torch.as_tensor(value, dtype=torch.float32 if not torch.is_tensor(value) else None)
        if fault:
            valid = False
        elif name == "velocity":  # finite, at most 10 km/s (a faster start underflows the CFL substep)
            speeds = t.double().norm(dim=-1) if t.numel() else t.double()
            valid = tuple(t.shape) in ((3,), (n, 3)) and bool(torch.isfinite(t).all()) and bool((speeds <= 1e4).all())
        else:
            valid = tuple(t.shape) in ((), (n,)) and _material_ok(name, t.double().reshape(-1).tolist())
        category = f"{name} {'valid' if valid else 'invalid'}"
        try:
            out = _velocity_argument(value, n) if name == "velocity" else _material_argument(name, value, n)
        except ArgumentError as exc:
            msg = str(exc)
            assert "\n" not in msg and msg.startswith(f"{FORWARD}: {name}"), msg
            tally.add(category, "false rejection" if valid else "our error")
            assert not valid, f"{name} = {value!r} refused: {msg}"
            return
        except Exception:
            tally.add(category, "traceback")
            raise
        tally.add(category, "silent acceptance" if not valid else "clean load")
        assert valid, f"{name} = {value!r} accepted"
        assert torch.equal(out.double(), t.double())

    prop()
    tally.report(capsys)
    assert tally.total("traceback") == tally.total("silent acceptance") == tally.total("false rejection") == 0
    assert tally.total("clean load") > 20 and tally.total("our error") > 100


# ----------------------------------------------------------------------------- CLI flag combinations

SCENE_FRAMES = {"bread": 90, "SPZ": 30, "FIT_FALSE": 30, "CELLS": 30, "GRIPS": 90}
RENDER_FLAGS = {
    "--load": ["drop", "none"],
    "--material": ["wood"],
    "--quality": ["draft"],
    "--particles": ["500"],
    "--preset": ["small", "paper"],
    "--frames": ["1", "3", "5"],
    "--export-ply": ["1", "3", "6"],
    "--devices": ["cpu", "cuda:1", "cpu,cuda:0", "cpu,cuda:0,cuda:1", "cpu,cpu", "cuda,cuda:0", "cpu,", "auto,cuda:0"],
    "--device": ["cpu", "cuda:1", "auto"],
    "--schedule": ["auto", "in-turn", "threads", "processes"],
    "--variants": ["full", "baseline,full", "baseline,stress_zero,full"],
    "--resolution": ["64x48", "32X32", "-64x48", "0x10", "-1x-1"],
}


def _device(name: str) -> str:
    """auto|cpu|cuda[:N] on the pretended two-GPU machine."""
    return {"cpu": "cpu", "auto": "cuda:0", "cuda": "cuda:0"}.get(name, name)


def render_violations(scene: str, flags: dict) -> set[str]:
    """The flags that do nothing (or are malformed) in this combination, stated from the README's rules."""
    bad = set()
    capture_flags = [f for f in ("--load", "--material", "--quality") if f in flags]
    if scene == "bread":
        bad.update(capture_flags)
    else:
        bad.update({"--particles"} & set(flags))
        if scene == "FIT_FALSE":
            bad.update(capture_flags)
        else:
            bad.update({"--preset"} & set(flags))
            if scene == "CELLS" and "--quality" in flags:
                bad.add("--quality")
            if scene == "GRIPS" and "--load" in flags:
                bad.add("--load")
    frames = int(flags.get("--frames", SCENE_FRAMES[scene]))
    if "--export-ply" in flags and int(flags["--export-ply"]) > frames:
        bad.add("--export-ply")
    if flags.get("--resolution", "1x1")[0] in "-0":
        bad.add("--resolution")
    variants = len(flags.get("--variants", "a,b,c").split(","))
    devices = None
    if "--devices" in flags:
        names = flags["--devices"].split(",")
        devices = [_device(d) for d in names if d]
        if "" in names:
            bad.add("--devices")
        if "--device" in flags:
            bad.add("--device")
        if len(set(devices)) < len(devices):
            bad.add("--devices")
    if devices and len(devices) > 1:
        if "--schedule" in flags:
            bad.add("--schedule")
        if len(devices) > variants:
            bad.add("--devices")
    elif flags.get("--schedule") in ("threads", "processes") and variants == 1:
        bad.add("--schedule")
    return bad


BENCH_FLAGS = {
    "--accuracy": None,
    "--quick": None,
    "--cases": ["bar"],
    "--from-json": ["saved.json"],
    "--steps": ["5"],
    "--warmup": ["1"],
    "--trials": ["1"],
    "--grid": ["16"],
    "--sort": ["interleaved"],
    "--no-graph": None,
    "--placements": ["1"],
    "--particles": ["1000"],
    "--device": ["cpu", "cuda:0", "auto"],
}
TABLE2 = {"--steps", "--warmup", "--trials", "--grid", "--sort", "--no-graph", "--placements", "--particles"}
FIGURES_FLAGS = {
    "--readme-only": None,
    "--protocol": ["quick"],
    "--only": ["ficus"],
    "--reuse": None,
    "--backend": ["torch"],
    "--device": ["cpu"],
}


def bench_violations(flags: dict) -> set[str]:
    if "--accuracy" not in flags:
        bad = {"--quick", "--cases", "--from-json"} & set(flags)
        if "--no-graph" in flags and _device(flags.get("--device", "auto")) == "cpu":
            bad.add("--no-graph")
        return bad
    bad = TABLE2 & set(flags)
    if "--from-json" in flags:
        bad |= {"--quick", "--cases", "--device"} & set(flags)
    return bad


def figures_violations(flags: dict) -> set[str]:
    return (set(FIGURES_FLAGS) - {"--readme-only"}) & set(flags) if "--readme-only" in flags else set()


@st.composite
def flag_case(draw):
    command = draw(st.sampled_from(["render-sim"] * 3 + ["bench", "figures"]))
    table = {"render-sim": RENDER_FLAGS, "bench": BENCH_FLAGS, "figures": FIGURES_FLAGS}[command]
    names = draw(st.lists(st.sampled_from(sorted(table)), max_size=5, unique=True))
    flags = {f: (None if table[f] is None else draw(st.sampled_from(table[f]))) for f in names}
    scene = draw(st.sampled_from(sorted(SCENE_FRAMES))) if command == "render-sim" else None
    return command, scene, flags


@pytest.fixture
def recorders(monkeypatch, tmp_path):
    import fracture_gs.paper.accuracy as accuracy
    import fracture_gs.paper.bench as bench
    import fracture_gs.paper.figures as figures
    import fracture_gs.paper.readme as readme
    from fracture_gs.cli import devices

    calls = []

    def accuracy_run(device, out_dir, **kw):
        calls.append("accuracy")
        (out_dir / "accuracy.md").write_text("table")

    monkeypatch.setattr(devices, "_cuda_devices", lambda: (True, 2, "pretended"))
    monkeypatch.setattr(devices, "_prepare_warp", lambda init=True: None)
    monkeypatch.setattr(
        runner,
        "run_render_sim",
        lambda cfg, variants, device, out_dir, **kw: calls.append("render-sim") or ok_summary(cfg, variants, device),
    )
    monkeypatch.setattr(bench, "run_bench", lambda **kw: calls.append("bench") or {"ok": True})
    monkeypatch.setattr(accuracy, "run_accuracy", accuracy_run)
    monkeypatch.setattr(accuracy, "write_outputs", lambda data, out_dir: accuracy_run(None, out_dir))
    monkeypatch.setattr(figures, "run_figures", lambda device, out_dir, **kw: calls.append("figures") or {})
    monkeypatch.setattr(readme, "refresh_readme", lambda out_dir: calls.append("readme") or "readme")
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("FRACTURE_GS_DEBUG", raising=False)
    saved = {"results": [], "caption": "", "command": "", "device_name": ""}  # an accuracy.json with no rows
    (tmp_path / "saved.json").write_text(json.dumps(saved))
    meta = {"command": "", "date": "", "device_name": "", "wall_s": 0.0, "device": "cpu", "out_arg": "out"}
    for out in (tmp_path / "out", tmp_path / "figures" / "out"):  # what --readme-only rewrites README.md from
        out.mkdir(parents=True)
        (out / "summary.json").write_text(json.dumps({"meta": meta}))
    from test_bad_input_api import SPZ

    spz = SPZ.as_posix()
    texts = {
        "FIT_FALSE": f'extends = "capture"\nscene = "{spz}"\n[capture]\nfit = false\n',
        "CELLS": f'extends = "capture"\nscene = "{spz}"\n[capture]\ncells_across = 40\n',
        "GRIPS": f'extends = "bread"\nscene = "{spz}"\n',
    }
    scenes = {"bread": "bread", "SPZ": spz}
    for name, text in texts.items():
        (tmp_path / f"{name}.toml").write_text(text)
        scenes[name] = str(tmp_path / f"{name}.toml")
    return calls, scenes


def test_fuzz_flag_combinations(recorders, capsys):
    calls, scenes = recorders
    tally = Tally("CLI flag combinations")
    rules = {"render-sim": None, "bench": bench_violations, "figures": figures_violations}

    @fuzz_settings(300)
    @given(flag_case())
    def prop(case):
        command, scene, flags = case
        violations = render_violations(scene, flags) if command == "render-sim" else rules[command](flags)
        argv = [command] + ([scenes[scene]] if scene else [])
        for f, v in flags.items():
            argv += [f] if v is None else [f, v]
        argv += ["--out", "out"]
        category = f"{command}{' ' + scene if scene else ''} {'refused' if violations else 'acts'}"
        before = len(calls)
        code, err, line = run_cli(cli.main, argv, capsys, tally, category)
        if code == 2:
            if not violations:
                tally.add(category, "false rejection")
                raise AssertionError(f"{argv} refused: {line}")
            assert any(f in line for f in violations), (violations, line)
            assert len(calls) == before, "refused after the run started"
            tally.add(category, "our error")
        else:
            if violations:
                tally.add(category, "silent acceptance")
                raise AssertionError(f"{argv} accepted (exit {code}) though {sorted(violations)} do nothing")
            assert code == 0 and len(calls) == before + 1, (argv, code, err)
            tally.add(category, "clean load")

    prop()
    tally.report(capsys)
    assert tally.total("traceback") == tally.total("silent acceptance") == tally.total("false rejection") == 0
    assert tally.total("clean load") > 30 and tally.total("our error") > 60
