"""Hostile input, item by item (issue 18, items 1–8): each bad input found by hand ends in one of our
exceptions (`FractureGSError`) with one sentence naming the file, flag or field, or in one CLI line with
exit code 2 — never another exception, a traceback, an allocation of gigabytes or a silent acceptance."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from plyfile import PlyData, PlyElement
from simutil import block, config, particles

from fracture_gs import cli
from fracture_gs import sim as S
from fracture_gs.errors import ConfigError, FractureGSError, PlyError, SimulationError
from fracture_gs.io import load_ply
from fracture_gs.io.config import config_from_dict, load_config, validate
from fracture_gs.io.config.dump import config_to_dict
from fracture_gs.io.ply import load_ply_lenient

pytestmark = pytest.mark.usefixtures("one_thread")

NAN, INF = float("nan"), float("inf")
BASE = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2"]
BASE += ["rot_0", "rot_1", "rot_2", "rot_3"]


def one_line_error(argv, capsys) -> str:
    """Run the CLI in-process; assert exit 2 and exactly one `fracture-gs: error:` line; return it."""
    code = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("fracture-gs: error: "), err
    return lines[0]


def gaussians(n: int = 6, order: str = "<", extra=(), text: bool = False, path=None, mutate=None):
    """A small valid 3DGS PLY (nx ny nz like the reference trainer), byte order `order`, extra properties."""
    dtype = [(name, order + "f4") for name in ["x", "y", "z", "nx", "ny", "nz"] + BASE[3:]] + list(extra)
    v = np.zeros(n, dtype=dtype)
    v["x"], v["rot_0"] = np.linspace(0, 1, n), 1.0
    for i in range(3):
        v[f"scale_{i}"] = -4.0
    for name, kind in extra:
        v[name] = (np.arange(n) % 3).astype(np.dtype(kind))
    if mutate:
        mutate(v)
    PlyData([PlyElement.describe(v, "vertex")], text=text, byte_order=order if order in "<>" else "=").write(str(path))
    return path


# 1 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("far", [1e4, 3e38])
def test_item1_far_particle_never_sizes_a_huge_auto_grid(far):
    """One floater far away makes the automatic grid huge: refused in one sentence before any allocation
    (it names the cap and the floaters), for x = 1e4 as for x = 3e38 (no overflow TypeError)."""
    x, vol = block((0.3,) * 3, (0.4,) * 3, 1 / 32)
    x = torch.cat([x, torch.tensor([[far, 0.35, 0.35]])])
    with pytest.raises(SimulationError, match="max_grid_cells.*floaters"):
        S.Simulator(S.SimConfig(dx=1 / 32, grid="auto"), particles(x, vol))


# 2 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("text", [False, True], ids=["binary", "ascii"])
def test_item2_big_endian_ply_with_extras_loads_like_little_endian(tmp_path, text):
    """A big-endian PLY with the trainer's nx ny nz and odd-sized extras (u1, u2, f8) in a packed record
    loads with the same values as its little-endian twin; the extras keep their values."""
    extra = [("flag", "u1"), ("tag", "u2"), ("weight", "f8")]
    big = load_ply(gaussians(order=">", extra=[(n, ">" + k) for n, k in extra], text=text, path=tmp_path / "b.ply"))
    little = load_ply(gaussians(order="<", extra=[(n, "<" + k) for n, k in extra], path=tmp_path / "l.ply"))
    torch.testing.assert_close(big.means, little.means)
    torch.testing.assert_close(big.scales, little.scales)
    assert set(big.extra) == {"nx", "ny", "nz", "flag", "tag", "weight"}
    for name in big.extra:
        assert big.extra[name].tolist() == little.extra[name].tolist() == big.extra[name].tolist()
    assert big.extra["tag"].tolist() == [0, 1, 2, 0, 1, 2]


# 3 ------------------------------------------------------------------------------------------------


def test_item3_grid_shape_is_bounded_before_allocation():
    """An explicit 100000³ grid fails validate (a config error naming sim.grid_shape and the GiB) and the
    Python API (SimulationError), never an out-of-memory traceback."""
    d = config_to_dict(load_config("bread"))
    d["sim"].update(grid="explicit", grid_shape=[100000] * 3)
    with pytest.raises(ConfigError, match=r"sim\.grid_shape.*GiB"):
        validate(config_from_dict(d, "huge.toml"), "huge.toml")
    x, vol = block((0.3,) * 3, (0.4,) * 3, 1 / 32)
    with pytest.raises(SimulationError, match="max_grid_cells"):
        S.Simulator(S.SimConfig(dx=1 / 32, grid_shape=(100000,) * 3), particles(x, vol))


# 4 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("where", ["file", "under_file", "devnull", "empty"])
def test_item4_out_that_cannot_be_a_folder(where, tmp_path, capsys):
    """--out at an existing file, under a file, at /dev/null or empty: one line naming --out, exit 2."""
    f = tmp_path / "a_file"
    f.write_text("x")
    out = {"file": f, "under_file": f / "sub", "devnull": "/dev/null", "empty": ""}[where]
    line = one_line_error(["bench", "--device", "cpu", "--particles", "100", "--steps", "1", "--out", out], capsys)
    assert "--out" in line


# 5 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("prop,value", [("scale_0", 88.0), ("scale_1", -100.0)])
def test_item5_log_scales_whose_covariance_is_not_finite(tmp_path, prop, value):
    """exp(88)² overflows float32 and exp(−100) underflows it: load_ply names the property and vertex; the
    lenient loader (captured scenes) drops exactly that Gaussian."""

    def bad(v):
        v[prop][2] = value

    path = gaussians(path=tmp_path / "s.ply", mutate=bad)
    with pytest.raises(PlyError, match=f"{prop}.*vertex 2"):
        load_ply(path)
    gs, dropped = load_ply_lenient(path)
    assert dropped == 1 and len(gs) == 5 and torch.isfinite(gs.scales**2).all() and (gs.scales**2 > 0).all()


@pytest.mark.parametrize(
    "prop,kind,value",
    [("fgs_label", "f4", NAN), ("fgs_label", "f8", 3e9), ("fgs_label", "i4", -1), ("fgs_label", "f4", 1.5)]
    + [("fgs_interior", "f4", NAN), ("fgs_interior", "u1", 2)],
)
def test_item5_our_properties_are_checked(tmp_path, prop, kind, value):
    """fgs_label must be a non-negative int32 integer and fgs_interior 0 or 1: NaN never becomes True and
    3e9 never wraps to −2147483648."""

    def bad(v):
        v[prop][1] = value

    path = gaussians(path=tmp_path / "o.ply", extra=[(prop, "<" + kind)], mutate=bad)
    with pytest.raises(PlyError, match=f"{prop}.*vertex 1"):
        load_ply(path)


# 6 ------------------------------------------------------------------------------------------------

FIELD_VALUES = [
    ("initial_velocity", [NAN, 0.0, 0.0]),
    ("sim.grid_origin", [0.0, NAN, 0.0]),
    ("sim.gravity", [0.0, 0.0, -INF]),
    ("sim.boundaries.0.velocity", [INF, 0.0, 0.0]),
    ("sim.boundaries.0.lower", [NAN, 0.0, 0.0]),
    ("topology.point", [INF, 0.0, 0.0]),
    ("topology.latch_time", INF),
    ("render.camera.orbit_degrees", NAN),
    ("render.camera.eye", [NAN, 1.0, 1.0]),
    ("particles", 0),
    ("particles", -5),
    ("frames", 10**9),
    ("render.width", 200000),
    ("render.height", 0),
    ("name", ".."),
    ("name", "."),
    ("name", "a/b"),
    ("name", ""),
    ("material.E", INF),
    ("frame_dt", NAN),
]


@pytest.mark.parametrize("field,value", FIELD_VALUES, ids=[f"{f}={v}" for f, v in FIELD_VALUES])
def test_item6_validate_refuses_non_finite_and_unbounded_values(field, value):
    """validate names the field for every non-finite float or vector, unbounded count and unsafe name."""
    d = copy.deepcopy(config_to_dict(load_config("bread")))
    node, keys = d, field.split(".")
    for k in keys[:-1]:
        node = node[int(k)] if isinstance(node, list) else node.setdefault(k, {})
    node[keys[-1]] = value
    with pytest.raises(ConfigError) as err:
        validate(config_from_dict(d, "bad.toml"), "bad.toml")
    head = keys[0] if keys[0] != "sim" or keys[1] != "boundaries" else "sim.boundaries[0]"
    assert str(err.value).startswith("bad.toml: ") and head in str(err.value), err.value


def test_item6_nan_grid_origin_is_a_config_error_not_a_conversion_error(tmp_path, capsys):
    """The CLI path: a NaN grid_origin in a TOML (written as `nan`) is one line naming the field."""
    toml = tmp_path / "nan.toml"
    toml.write_text('extends = "bread"\n[sim]\ngrid_origin = [nan, 0.0, 0.0]\n')
    assert "sim.grid_origin" in one_line_error(["validate", toml], capsys)


# 7 ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", ["E_inf", "mass_inf", "all_outside", "nan_F"])
def test_item7_python_api_raises_typed_errors(case):
    """The Python API: E = inf with adaptive Δt, infinite mass, every particle outside an explicit grid
    and a NaN F each raise a SimulationError (a FractureGSError) naming the quantity."""
    x, vol = block((0.3,) * 3, (0.4,) * 3, 1 / 32)
    n = len(x)
    needle = {"E_inf": "E must be a finite", "mass_inf": "mass", "all_outside": "outside the grid", "nan_F": "F "}
    build = {
        "E_inf": lambda: (particles(x, vol, E=INF), config(32, adaptive_dt=True)),
        "mass_inf": lambda: (S.Particles(x=x, mass=torch.full((n,), INF), volume=torch.full((n,), vol)), config(32)),
        "all_outside": lambda: (particles(x + 5.0, vol), config(32)),
        "nan_F": lambda: (particles(x, vol, F=torch.full((n, 3, 3), NAN)), config(32)),
    }
    with pytest.raises(FractureGSError) as err:
        P, cfg = build[case]()
        S.Simulator(cfg, P).advance(0.01)
    assert isinstance(err.value, SimulationError) and needle[case] in str(err.value), err.value


# 8 ------------------------------------------------------------------------------------------------


def test_item8_config_files_that_are_not_plain_utf8_toml(tmp_path, capsys):
    """Non-UTF-8 bytes, extends = ".", a 2000-deep nested array: one line naming the file; a UTF-8 BOM
    (as Windows editors write) is accepted."""
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'extends = "bread"\nname = "caf\xe9"\n')
    assert "latin.toml" in (line := one_line_error(["validate", latin], capsys)) and "UTF-8" in line
    dot = tmp_path / "dot.toml"
    dot.write_text('extends = "."\n')
    assert "dot.toml: extends = '.'" in one_line_error(["validate", dot], capsys)
    deep = tmp_path / "deep.toml"
    deep.write_text("x = " + "[" * 2000 + "]" * 2000 + "\n")
    assert "deep.toml" in (line := one_line_error(["validate", deep], capsys)) and "deeply" in line
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b'\xef\xbb\xbfextends = "bread"\nframes = 3\n')
    assert load_config(bom).frames == 3


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["--resolution", "²x²"], "--resolution must be WxH with positive integers, got ²x²"),
        (["--resolution", "9000x100"], "over 8192"),
        (["--device", ""], "--device '' is not a device"),
        (["--device", " "], "is not a device"),
    ],
)
def test_item8_flags_with_odd_values(argv, needle, tmp_path, capsys):
    """Superscript digits, oversized images and an empty device are refused by name (not int() errors,
    not a silent 'auto')."""
    assert needle in one_line_error(["render-sim", "bread", "--out", tmp_path / "o", *argv], capsys)


def test_finite_checks_cover_every_float_field():
    """Every float (or float vector) field of a built-in config is reached by the finiteness walk: setting
    any one of them to NaN is refused by name."""
    d0 = config_to_dict(load_config("bread"))
    paths = []

    def walk(node, prefix):
        if isinstance(node, dict):
            for k, v in node.items():
                walk(v, f"{prefix}.{k}" if prefix else k)
        elif isinstance(node, list) and node and all(isinstance(v, dict) for v in node):
            for i, v in enumerate(node):
                walk(v, f"{prefix}.{i}")
        elif isinstance(node, float) or (isinstance(node, list) and node and isinstance(node[0], float)):
            paths.append(prefix)

    walk(d0, "")
    assert len(paths) > 30
    for path in paths:
        d = copy.deepcopy(d0)
        node, keys = d, path.split(".")
        for k in keys[:-1]:
            node = node[int(k)] if isinstance(node, list) else node[k]
        old = node[keys[-1]]
        node[keys[-1]] = [NAN, *old[1:]] if isinstance(old, list) else NAN
        with pytest.raises(ConfigError, match="finite|outside|must be"):
            validate(config_from_dict(d, "nan.toml"), "nan.toml")


def test_api_errors_share_one_base_class():
    """Typed errors from every layer of the Python API: an unknown built-in scene (SceneError), variant
    (SimulationError), render backend (RenderError) and provider (SimulationError) are all FractureGSError
    (and still ValueError for older callers), each with a sentence naming the value."""
    from fracture_gs import assets
    from fracture_gs.config import TopologyConfig
    from fracture_gs.errors import RenderError, SceneError
    from fracture_gs.render.splat import render
    from fracture_gs.sim.providers import make_provider
    from fracture_gs.variants import variant_spec

    cases = [
        (lambda: assets.build("teapot"), SceneError, "teapot"),
        (lambda: variant_spec("fastest"), SimulationError, "fastest"),
        (lambda: render(*([None] * 5), backend="opengl"), RenderError, "opengl"),
        (lambda: make_provider(TopologyConfig(provider="magic")), SimulationError, "magic"),
    ]
    for call, cls, needle in cases:
        with pytest.raises(cls, match=needle) as err:
            call()
        assert isinstance(err.value, FractureGSError) and isinstance(err.value, ValueError)


@pytest.mark.slow
def test_a_run_leaves_no_tensors_in_reference_cycles(tmp_path):
    """Memory comes back when a run ends, without waiting for Python's cycle collector (which a GPU out
    of memory never triggers): after render-sim, nothing the run allocated sits in a reference cycle
    (the soak found each run's simulators held until a full collection through Simulator ↔ Diagnostics)."""
    import gc

    from fracture_gs.render_sim import run_render_sim

    cfg = load_config("bread")
    cfg.frames, cfg.particles, cfg.render.backend = 2, 1500, "torch"
    gc.collect()
    gc.disable()
    try:
        run_render_sim(cfg, ["baseline", "full"], "cpu", tmp_path / "run", progress=False)
        gc.set_debug(gc.DEBUG_SAVEALL)
        gc.collect()
        held = [o for o in gc.garbage if torch.is_tensor(o) or type(o).__name__ in ("Simulator", "Grid", "Diagnostics")]
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        gc.enable()
    assert not held, [type(o).__name__ for o in held[:10]]


def test_grid_larger_than_free_gpu_memory_is_refused(monkeypatch):
    """On CUDA the grid's buffers are checked against the device's free memory before allocation (seen on an
    H200: a 2048³ grid, 256 GiB, against 139 GiB free); here with the free-memory query stubbed."""
    from fracture_gs.sim.grid.domain import check_device_memory

    monkeypatch.setattr(torch.cuda, "mem_get_info", lambda device=None: (10 * 2**30, 80 * 2**30))
    with pytest.raises(SimulationError, match=r"needs ≈ 20.00 GiB but cuda:0 has 10.00 GiB free"):
        check_device_memory(20 * 2**30, "cuda:0", (1024, 1024, 640))
    check_device_memory(8 * 2**30, "cuda:0", (512, 512, 1024))  # fits in 90 % of what is free
    check_device_memory(10**15, "cpu", (10, 10, 10))  # the CPU is bounded by sim.max_grid_cells only
