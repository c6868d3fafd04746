"""Regenerate the paper's evidence: Tables 1–5 and the figures (`fracture-gs figures`, `apps/make_figures.py`).

Every number comes from rerunning the experiment configs (`configs/exp_table*.toml`) on the
built-in scenes with the paper's protocol (section 5.1):

=========  ======  =========  =====  ==================  ======================================
scene      frames  frame_dt   latch  post-latch window   what
=========  ======  =========  =====  ==================  ======================================
ficus      44      0.04 s     23     frames 23–43        Tables 1, 3, 5; teaser; multi-scene grid
bread      90      0.01 s     10     frames 10–89        Tables 1, 3, 5; multi-scene grid
plane_drop 60      0.01 s     0      all                 Table 4, Panel A
recontact  30      0.005 s    0      all                 Table 4, Panel B; method figure
=========  ======  =========  =====  ==================  ======================================

The latch frame is not imposed: the stress-guided provider finds it, and the tables report the
frame it found. The post-latch window runs from the measured latch frame to the last frame.

Protocols (`--protocol`):

* ``paper`` — Δx = 1/128 and the paper's particle counts (ficus 171,553, bread 182,959): a GPU
  job, the default on CUDA.
* ``quick`` — CPU sized, the default on the CPU: a few thousand particles, Δx = 1/32 for bread,
  ficus and plane_drop (so each cell still holds ≈ 6 particles), the ficus protocol compressed
  4× in time (frame_dt 0.01 s, the grip 4× faster: its loading is quasi-static, so the latch
  frame and post-latch window keep their frame numbers), recontact at Δx = 1/64 on a grid
  fitted to the blocks, and `min_particles` of the stress event scaled to the particle count
  where noted. Every table caption states the protocol, the particle count and Δx. Use it to
  check the qualitative story; report numbers from ``paper``.

Outputs in OUT: ``tables/table{1..5}_*.{md,csv,tex}``, ``fig_teaser.png``, ``fig_multiscene.png``,
``fig_method.png``, ``fig_opening_mixing.png``, with ``--only fragments`` (or all groups) ``fig_shatter.png``
(plate_drop) and ``tables/table_fragments.*`` (K against time, memory and contact: `fragments.py`),
``data/*.json`` (per-frame metrics of every run),
``summary.json`` and ``README.md`` (each table and figure with the command that made it).
"""

from __future__ import annotations

import datetime
import json
import platform
import time
from pathlib import Path
from typing import Iterable, Optional

import torch

from ..config import SceneConfig
from ..io.config import load_config
from .experiments import ExperimentRun, _load_cache, _save_cache, run_experiment, same_physics
from .fragments import fragments_table
from .paper_tables import _notes, _protocol_note, table1, table2, table3, table4, table5
from .plots import curve_series, curves_figure, method_figure, method_slice, multiscene_figure, teaser_figure
from .protocol import PROTOCOLS, _scene_render_size, prepare
from .readme import merged_figures, readme_text

# --------------------------------------------------------------------------------------------
# orchestration


EXPERIMENTS = {
    # key: (config, variants, what it feeds)
    "ficus": (
        "exp_table3_ficus",
        ("baseline", "probe_latch", "stress_zero", "full"),
        "Tables 1, 3; teaser; grid; curves",
    ),
    "bread": ("exp_table3_bread", ("baseline", "probe_latch", "stress_zero", "full"), "Tables 1, 3; grid; curves"),
    "plane_drop": ("exp_table4a_plane_drop", ("stress_zero", "full"), "Table 4 Panel A"),
    "recontact": ("exp_table4b_recontact", ("local_multifield", "full"), "Table 4 Panel B; method figure"),
    "ficus_vlm": ("exp_table5_ficus_vlm", ("full",), "Table 5"),
    "ficus_manual": ("exp_table5_ficus_manual", ("full",), "Table 5"),
    "bread_vlm": ("exp_table5_bread_vlm", ("full",), "Table 5"),
    "bread_manual": ("exp_table5_bread_manual", ("full",), "Table 5"),
    "plate_drop": ("plate_drop", ("full",), "shatter figure"),
}
GROUPS = {
    "ficus": ("ficus", "ficus_vlm", "ficus_manual"),
    "bread": ("bread", "bread_vlm", "bread_manual"),
    "interaction": ("plane_drop", "recontact"),
    "bench": (),
    "fragments": ("plate_drop",),  # and the K table (`fragments.fragments_table`)
}
TABLE1_CONFIGS = {"ficus": "exp_table1_ficus", "bread": "exp_table1_bread"}


def _teaser_frames(latch, frames):
    if latch is None:
        return [frames // 2, (3 * frames) // 4, frames]
    span = frames - latch
    return sorted({latch + round(span / 3), latch + round(2 * span / 3), frames})


def _shatter_frames(latch, frames):
    """Before the impact, just after it, while the pieces slide, and at the end."""
    return sorted({round(0.33 * frames), round(0.5 * frames), round(0.7 * frames), frames})


def _grid_frames(latch, frames):
    return [frames]


def _region(topology, cfg: SceneConfig, frame: int, width: int, height: int):
    """Inset region (cx, cy, r) of the latched interface in the frame's camera, or None."""
    from ..render import compose
    from ..render.camera import from_config

    if topology is None:
        return None
    cam = from_config(cfg.render.camera, width, height, t=frame / max(cfg.frames, 1))
    try:
        return compose.interface_region(topology.point, topology.normal, 0.04, cam)
    except ValueError:
        return None


def _try_plot(fn, *args) -> bool:
    """Draw a matplotlib figure; on a machine without matplotlib (a bare GPU image) skip it: the
    cached data in OUT/data let `--reuse` draw it elsewhere."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print(f"matplotlib is not installed: {fn.__name__} skipped (rerun with --reuse where it is)", flush=True)
        return False
    fn(*args)
    return True


def run_figures(
    device: str = "cpu",
    out_dir="figures/out",
    protocol: Optional[str] = None,
    only: Optional[Iterable[str]] = None,
    reuse: bool = False,
    progress: bool = True,
    command: Optional[str] = None,
    render_backend: Optional[str] = None,
) -> dict:
    """Rerun the paper's experiments and write Tables 1–5 and the figures into `out_dir`.

    `protocol`: "quick" (default on the CPU) or "paper" (default on CUDA). `only`: groups to run
    now ("ficus", "bread", "interaction", "bench"; default all); with `reuse`, runs cached in
    `out_dir/data` from earlier calls of the same protocol are loaded instead of rerun, so a long
    GPU job can be split over several calls (and the figures redrawn elsewhere from the cache).
    `render_backend` overrides the scenes' renderer ("torch" avoids compiling gsplat on a fresh
    GPU machine). Returns a short summary (also `summary.json`)."""
    device = str(device)
    if command is None:  # what was typed, as far as the arguments tell
        command = f"fracture-gs figures --device {device} --out {out_dir}" + (
            f" --protocol {protocol}" if protocol else ""
        )
    threads = torch.get_num_threads()
    if not device.startswith("cuda"):
        # Warp's CPU kernels are single-threaded; torch's OpenMP threads only slow the small
        # per-substep tensor ops (the strided grid clear ran 3x slower with 2 threads on a busy CPU)
        torch.set_num_threads(1)
    try:
        return _run_figures(device, out_dir, protocol, only, reuse, progress, command, render_backend)
    finally:
        torch.set_num_threads(threads)


def _run_figures(device, out_dir, protocol, only, reuse, progress, command, render_backend=None) -> dict:
    t_start = time.perf_counter()
    protocol = protocol or ("paper" if device.startswith("cuda") else "quick")
    if protocol not in PROTOCOLS:
        raise ValueError(f"--protocol {protocol!r} is unknown; use quick or paper")
    out = Path(out_dir)
    tables_dir, data_dir = out / "tables", out / "data"
    tables_dir.mkdir(parents=True, exist_ok=True)
    only = set(only) if only else set(GROUPS)
    unknown = only - set(GROUPS)
    if unknown:
        raise ValueError(f"unknown group(s) {', '.join(sorted(unknown))}; choose from {', '.join(GROUPS)}")
    torch.manual_seed(0)

    exps: dict = {}
    prepared = {k: prepare(load_config(cfg_name), protocol) for k, (cfg_name, _, _) in EXPERIMENTS.items()}
    for k in ("ficus", "bread"):  # rendered panels: the scene config's aspect ratio
        base = load_config(EXPERIMENTS[k][0])
        prepared[k].cfg.render.width, prepared[k].cfg.render.height = _scene_render_size(base, protocol)
        if render_backend:
            prepared[k].cfg.render.backend = render_backend
    wanted = [k for g in only for k in GROUPS[g]]

    def get(key):
        cfg_name, variants, _ = EXPERIMENTS[key]
        prep = prepared[key]
        if key in exps:
            return exps[key]
        # Table 5's manual parameters equal the scene config's: reuse the Table 3 Full run
        if key.endswith("_manual"):
            scene = key.split("_")[0]
            base = exps.get(scene)
            if base is not None and same_physics(base.prepared.cfg, prep.cfg) and "full" in base.runs:
                exps[key] = ExperimentRun(
                    prep.cfg.name,
                    base.scene,
                    prep,
                    base.particles,
                    {"full": base.runs["full"]},
                    base.topology,
                    base.device,
                )
                exps[key].reused_from = base.name
                return exps[key]
        cached = _load_cache(key, prep, data_dir) if (reuse or key not in wanted) else None
        if cached is not None:
            exps[key] = cached
            return cached
        if key not in wanted:
            return None
        render = render_variants = state = None
        if key == "ficus":
            render, render_variants = (
                (lambda L, F: sorted(set(_teaser_frames(L, F)) | set(_grid_frames(L, F)))),
                ("baseline", "stress_zero", "full"),
            )
        elif key == "bread":
            render, render_variants = _grid_frames, ("baseline", "stress_zero", "full")
        elif key == "plate_drop":
            render, render_variants = _shatter_frames, ("full",)
        elif key == "recontact":
            state = lambda sim, f: method_slice(sim) if sim.cfg.variant == "full" and f > 0 else None  # noqa: E731
        if progress:
            print(f"{cfg_name}: {', '.join(variants)} ({'; '.join(prep.notes)})", flush=True)
        exp = run_experiment(
            prep,
            variants,
            device,
            render=render,
            render_variants=render_variants,
            state_frames=state,
            progress=progress,
        )
        _save_cache(exp, data_dir)
        exps[key] = exp
        return exp

    for key in EXPERIMENTS:
        get(key)

    # Table 1 runs the same configs as Table 3 restricted to two variants: check, then reuse
    t1 = {}
    for scene, name in TABLE1_CONFIGS.items():
        exp = exps.get(scene)
        if exp is not None:
            c1 = prepare(load_config(name), protocol).cfg
            if same_physics(c1, exp.prepared.cfg):
                t1[scene] = exp
            else:  # pragma: no cover - configs diverged: run Table 1 on its own
                e = run_experiment(
                    prepare(load_config(name), protocol), ("stress_zero", "full"), device, progress=progress
                )
                _save_cache(e, data_dir)
                t1[scene] = e

    tables = []
    made = []
    if t1:
        made.append(table1(t1, command))
    if "bench" in only:
        if progress:
            print("Table 2: timing the four branches (apps.bench.time_branches)", flush=True)
        made.append(table2(device, protocol, command))
    if "fragments" in only:
        if progress:
            print("K fragments: timing and pressing the shattered ficus (paper.fragments)", flush=True)
        made.append(fragments_table(device, protocol, command))
    if exps.get("ficus") or exps.get("bread"):
        made.append(table3({k: exps[k] for k in ("ficus", "bread") if exps.get(k)}, command))
    if exps.get("plane_drop") or exps.get("recontact"):
        made.append(table4(exps.get("plane_drop"), exps.get("recontact"), command))
    t5 = {k: exps[k] for k in ("ficus_vlm", "ficus_manual", "bread_vlm", "bread_manual") if exps.get(k)}
    if t5:
        tab = table5(t5, command)
        reused = [k for k in t5 if getattr(t5[k], "reused_from", None)]
        if reused:
            tab.caption += (
                " Manual rows reuse the Full run of Table 3 ("
                + ", ".join(t5[k].reused_from for k in reused)
                + "): their resolved configs are identical apart from name and variant list."
            )
        made.append(tab)
    for t in made:
        tables.append({"table": t, "paths": [str(p) for p in t.write(tables_dir)]})

    figures = []
    fx = exps.get("ficus")
    if fx is not None and all(fx.runs[v].images for v in ("baseline", "full")):
        frames = _teaser_frames(fx.latch_frame, fx.prepared.cfg.frames)
        c = fx.prepared.cfg
        regions = {f: _region(fx.topology, c, f, c.render.width, c.render.height) for f in frames}
        p = out / "fig_teaser.png"
        teaser_figure({v: fx.runs[v].images for v in ("baseline", "full")}, frames, c.frame_dt, p, regions)
        figures.append(
            {
                "title": "Figure 1: teaser (Ficus, baseline vs FractureFields)",
                "path": str(p),
                "function": "teaser_figure",
                "caption": f"Shared-field baseline (top) and FractureFields (bottom) at matched times after the latch "
                f"(frame {fx.latch_frame}); circular insets magnify the latched interface. {_protocol_note(fx)}.",
            }
        )
    panels, regions, times = {}, {}, {}
    for s in ("ficus", "bread"):
        e = exps.get(s)
        if e is not None and all(e.runs[v].images for v in ("baseline", "stress_zero", "full")):
            F = e.prepared.cfg.frames
            panels[s] = {v: e.runs[v].images[F] for v in ("baseline", "stress_zero", "full")}
            c = e.prepared.cfg
            regions[s] = _region(e.topology, c, F, c.render.width, c.render.height)
            times[s] = f"(t = {F * c.frame_dt:.2f} s)"
    if panels:
        p = out / "fig_multiscene.png"
        multiscene_figure(panels, p, regions, times=times)
        figures.append(
            {
                "title": "Figure 2: multi-scene comparison",
                "path": str(p),
                "function": "multiscene_figure",
                "caption": "Rows: scenes; columns: shared-field baseline, Stress-Zero, FractureFields at the last "
                "frame (matched post-fracture time). " + _notes([exps[s] for s in panels]),
            }
        )
    pd = exps.get("plate_drop")
    if pd is not None and pd.runs.get("full") is not None and pd.runs["full"].images:
        c = pd.prepared.cfg
        frames = _shatter_frames(None, c.frames)
        p = out / "fig_shatter.png"
        teaser_figure({"full": pd.runs["full"].images}, frames, c.frame_dt, p, variants=("full",))
        K = max(r.get("fragments", 0) for r in pd.runs["full"].rows) if pd.runs["full"].rows else 0
        figures.append(
            {
                "title": "Figure: shatter (plate_drop, FractureFields, repeated fracture)",
                "path": str(p),
                "function": "teaser_figure",
                "caption": f"A plate dropped on a rough floor breaks on impact and its pieces break again (the "
                f"stress provider's repeated fracture), {K} pieces at the end, each drawn in its own colour; "
                f"Coulomb friction between pieces and on the floor. " + _protocol_note(pd) + ".",
            }
        )
    rc = exps.get("recontact")
    if rc is not None and rc.runs.get("full") is not None and rc.runs["full"].states:
        states = rc.runs["full"].states
        best = max(states, key=lambda f: (states[f]["n_projected"], -f))
        p = out / "fig_method.png"
        if _try_plot(method_figure, states[best], p):
            figures.append(
                {
                    "title": "Figure 3: method, from simulation data (re-contact, FractureFields)",
                    "path": str(p),
                    "function": "method_figure",
                    "caption": f"A 2D slice of the re-contact run (variant full) at frame {best}, the frame with "
                    f"the most contact-projected nodes: particles coloured by fragment (band outlined), grid nodes "
                    f"by the set of active fields, contact impulses on field 1 as arrows (equal and opposite on "
                    f"field 0). " + _protocol_note(rc) + ".",
                }
            )
    series = {
        s: curve_series(exps[s], ("baseline", "probe_latch", "stress_zero", "full"))
        for s in ("ficus", "bread")
        if exps.get(s)
    }
    if series:
        p = out / "fig_opening_mixing.png"
        if _try_plot(curves_figure, series, p):
            figures.append(
                {
                    "title": "Figure 4: opening and mixing over time per variant",
                    "path": str(p),
                    "function": "curves_figure",
                    "caption": "Interface opening/Δx (left) and mixing E_mix (right; realized solid, counterfactual "
                    "dashed, symlog axis: Full's realized mixing is exactly 0) per variant after the latch. "
                    + _notes([exps[s] for s in series]),
                }
            )

    wall = time.perf_counter() - t_start
    cuda = device.startswith("cuda")
    meta = {
        "command": command,
        "date": datetime.date.today().isoformat(),
        "device": device,
        "protocol": protocol,
        "device_name": torch.cuda.get_device_name(torch.device(device))
        if cuda
        else f"CPU, {platform.processor() or platform.machine()}",
        "wall_s": wall,
        "out_arg": str(out_dir),
    }
    figures = [{**f, "command": f.get("command", command)} for f in figures]  # each figure names its own call
    if only != set(GROUPS):  # a partial call (`--only`) keeps the figures an earlier call made
        figures = merged_figures(out, figures)
    (out / "README.md").write_text(readme_text(out, tables, figures, meta))
    summary = {
        "out_dir": str(out),
        "protocol": protocol,
        "device": device,
        "wall_s": round(wall, 1),
        "tables": [Path(t["paths"][0]).name for t in tables],
        "figures": [Path(f["path"]).name for f in figures],
        "latch_frames": {k: e.latch_frame for k, e in exps.items() if e is not None},
    }
    entries = [{**f, "path": Path(f["path"]).relative_to(out).as_posix()} for f in figures]
    (out / "summary.json").write_text(json.dumps({**summary, "meta": meta, "figure_entries": entries}, indent=2))
    return summary
