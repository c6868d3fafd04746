"""Tables 1–5 of the paper from experiment runs (Table 2 from the transfer benchmark)."""

from __future__ import annotations

import contextlib
import math
import platform
from typing import Optional, Sequence

import torch

from ..runtime import side_stream
from ..variants import variant_spec
from .experiments import ExperimentRun, ablation_stats, transfer_stats
from .protocol import QUICK, SCENE_NAMES
from .tables import Column, Panel, Table

# the five tables

TABLE_KEYS = (
    "table1_transfer",
    "table2_efficiency",
    "table3_ablation",
    "table4_interaction",
    "table5_material_prior",
    "table_fragments",  # `fragments.fragments_table`
)


def _protocol_note(exp: ExperimentRun) -> str:
    c = exp.prepared.cfg
    latch = exp.latch_frame
    extra = ""
    if exp.prepared.protocol == "quick" and exp.prepared.time_scale != 1.0:
        extra = f" (time compressed {exp.prepared.time_scale:g}×: loading {exp.prepared.time_scale:g}× faster)"
    if exp.prepared.protocol == "quick" and QUICK.get(exp.scene, {}).get("load_scale", 1.0) != 1.0:
        extra += f", loading ×{QUICK[exp.scene]['load_scale']:g} (calibrated latch)"
    if exp.prepared.protocol == "quick" and exp.scene in QUICK and "min_particles" in QUICK[exp.scene]:
        extra += f", stress event min_particles {c.topology.min_particles}"
    win = f"post-latch window frames {latch}–{c.frames}" if latch is not None else "no latch"
    return (
        f"{SCENE_NAMES.get(exp.scene, exp.scene)}: {exp.prepared.protocol} protocol, {exp.particles} particles, "
        f"Δx = 1/{round(1 / c.sim.dx)}, {c.frames} frames × {c.frame_dt:g} s{extra}, latch frame {latch}, {win}"
    )


def _notes(exps: Sequence[ExperimentRun]) -> str:
    out = []
    for e in exps:
        n = _protocol_note(e)
        if n not in out:
            out.append(n)
    return "; ".join(out) + "."


def table1(exps: dict, command: str = "") -> Table:
    """Post-fracture transfer diagnostics (Stress-Zero vs Full) for ficus and bread."""
    cols = [
        Column("scene", "Scene", "Scene", "text"),
        Column("transfer", "Transfer", "Transfer", "text"),
        Column("cf", "E_mix^cf mean/max", r"$E_{\mathrm{mix}}^{\mathrm{cf}}$ mean/max", "meanmax"),
        Column("real", "E_mix^real mean/max", r"$E_{\mathrm{mix}}^{\mathrm{real}}$ mean/max", "meanmax"),
        Column("shared", "Shared (%)", r"Shared (\%)", "num"),
        Column("mass_residual", "max E_m", r"$\max E_m$", "num"),
    ]
    rows, used = [], []
    for scene in ("ficus", "bread"):
        exp = exps.get(scene)
        if exp is None:
            continue
        used.append(exp)
        for v in ("stress_zero", "full"):
            if v not in exp.runs:
                continue
            st = transfer_stats(exp.runs[v], exp.latch_frame)
            rows.append({"scene": SCENE_NAMES[scene], "transfer": variant_spec(v).transfer, **st})
    caption = (
        "Post-fracture transfer diagnostics. Mixing entries are post-latch mean/maximum over the window; for Full, "
        "realized mixing is a structural zero of the P2G/G2P routing. " + _notes(used)
    )
    return Table(
        "table1_transfer",
        "Table 1: post-fracture transfer diagnostics",
        [Panel(cols, rows)],
        caption,
        "tab:transfer_validation",
        command,
    )


def table2(device: str, protocol: str, command: str = "") -> Table:
    """Transfer efficiency of the four branches, timed by `fracture_gs.paper.bench.time_branches`."""
    cols = [
        Column("branch", "Branch", "Branch", "text"),
        Column("passes", "Passes (P2G/G2P/frag)", "Passes (P2G/G2P/frag)", "text"),
        Column("median_ms", "Median (ms)", "Median (ms)", "num"),
        Column("relative", "Relative", "Relative", "num"),
        Column("grid_mib", "Grid-buffer footprint (MiB)", "Grid-buffer footprint (MiB)", "num"),
    ]
    cuda = device.startswith("cuda")
    particles = None if (cuda and protocol == "paper") else 20_000
    steps, warmup, trials = (200, 20, 3) if cuda else (20, 3, 3)
    args = (particles, device, steps, warmup, trials, 5 if cuda else 1)
    if cuda:
        rows, n, cells, dx = _table2_rows(*args)
    else:  # a fresh process: this one's state (heap, torch's threads) made CPU wall clocks swing by over half
        import multiprocessing

        with multiprocessing.get_context("spawn").Pool(1) as pool:
            rows, n, cells, dx = pool.apply(_table2_rows, args)
    name = (
        torch.cuda.get_device_name(torch.device(device))
        if cuda
        else (platform.processor() or platform.machine() or "unknown")
    )
    where = (
        f"{name}, CUDA events; per branch the median over 5 fresh-memory builds × {trials} trials (round-robin), "
        f"each a median of {steps} substeps after {warmup} warm-up"
        if cuda
        else f"CPU ({name}; Warp runs kernels single-threaded here): wall-clock medians over {steps} substeps × "
        f"{trials} trials (round-robin) in a fresh process, not comparable with GPU timings"
    )
    caption = (
        f"Transfer efficiency on the ficus at {n} particles, grid {cells}³ (Δx = 1/{round(1 / dx)}). "
        f"Runtime normalized to Shared Field; scope: grid reset, P2G, normalization, contact projection, G2P "
        f"(no stress, rendering, probing or diagnostics). The memory column is the branch's grid-buffer footprint. "
        f"Measured on {where}."
    )
    title = "Table 2: transfer efficiency" + ("" if cuda else " (CPU)")
    return Table(
        "table2_efficiency",
        title,
        [Panel(cols, [dict(r) for r in rows])],
        caption,
        "tab:transfer_efficiency_v3",
        command,
    )


def _table2_rows(particles, device: str, steps: int, warmup: int, trials: int, placements: int):
    """`bench.time_branches` on the bench state: (rows, particles, grid cells, Δx)."""
    from . import bench

    cfg, P, topo = bench.bench_state(particles, device)
    stream = side_stream(device) if device.startswith("cuda") else None
    with torch.cuda.stream(stream) if stream is not None else contextlib.nullcontext():
        rows = bench.time_branches(
            cfg,
            P,
            topo,
            device,
            steps=steps,
            warmup=warmup,
            trials=trials,
            graph=stream is not None,
            placements=placements,
        )
    return rows, len(P), cfg.sim.grid_shape[0], cfg.sim.dx


def table3(exps: dict, command: str = "") -> Table:
    """Real-scene component ablation: four variants per scene."""
    cols = [
        Column("scene", "Scene", "Scene", "text"),
        Column("method", "Method", "Method", "text"),
        Column("opening", "Opening/Δx", r"Opening/$\Delta x$", "num"),
        Column("reapproach", "Reapp.", "Reapp.", "num"),
        Column("stringing", "Stringing", "Stringing", "num"),
        Column("mass_residual", "max E_m", r"$\max E_m$", "num"),
        Column("separated", "Sep.", "Sep.", "bool"),
    ]
    rows, used, bold = [], [], {}
    for scene in ("ficus", "bread"):
        exp = exps.get(scene)
        if exp is None:
            continue
        used.append(exp)
        for v in ("baseline", "probe_latch", "stress_zero", "full"):
            if v in exp.runs:
                st = ablation_stats(exp.runs[v], exp.latch_frame)
                if v == "full":
                    bold[(0, len(rows), "opening")] = True
                rows.append(
                    {
                        "scene": SCENE_NAMES[scene],
                        "method": variant_spec(v).label.replace(" (Full)", "").replace("FractureFields", "Full"),
                        **st,
                    }
                )
    caption = (
        "Real-scene component ablation. Opening is the final mean interface opening over Δx, Reapp. the maximum "
        "re-approach ratio, Stringing the mean band anisotropy ln(s_max/s_min) of F over the post-latch window, "
        "Sep. the common 0.1Δx opening rule. " + _notes(used)
    )
    return Table(
        "table3_ablation",
        "Table 3: real-scene component ablation",
        [Panel(cols, rows)],
        caption,
        "tab:real_ablation_v2",
        command,
        bold,
    )


def _success(pen_max, crossing) -> Optional[bool]:
    """The paper's Task Success: max penetration/Δx < 0.1 and no identity crossing."""
    if pen_max is None:
        return None
    return bool(pen_max < 0.1 and (crossing or 0) == 0)


def fragment_aware(rows: list) -> dict:
    """Table 4's fragment-aware columns over a run's rows: the deepest depth/Δx of a particle behind another
    fragment's surface (`penetration.surface_depth`), the most particles deeper than 0.1Δx in one frame, the
    deepest particle behind a plane collider/Δx, and their Task Success: no particle deeper than 0.1Δx behind
    another piece, none more than half a cell behind the collider (a node-based collider's resolution: it
    acts on nodes behind the plane, so particles come to rest with their centres up to half a cell past it)."""
    latched = [r for r in rows if "fragment_penetration" in r]
    if not latched:
        return {"frag_pen": None, "frag_cross": None, "collider": None, "frag_success": None}
    pen = max(float(r["fragment_penetration"]) for r in latched)
    cross = max(int(r["fragment_crossing"]) for r in latched)
    below = max(int(r.get("collider_crossing", 0)) for r in latched)
    return {
        "frag_pen": pen,
        "frag_cross": cross,
        "collider": max(float(r.get("collider_depth", 0.0)) for r in latched),
        "frag_success": bool(pen < 0.1 and cross == 0 and below == 0),
    }


FRAGMENT_AWARE_COLUMNS = [
    Column("frag_pen", "Frag. pen./Δx", r"Frag.\ pen./$\Delta x$", "num"),
    Column("frag_cross", "particles > 0.1Δx", r"particles $> 0.1\Delta x$", "int"),
    Column("collider", "behind plane/Δx", r"behind plane/$\Delta x$", "num"),
    Column("frag_success", "Task Success (fragment-aware)", "Task Success (fragment-aware)", "bool"),
]
FRAGMENT_AWARE_CAPTION = (
    " Fragment-aware columns (not in the paper): Frag. pen. is the deepest depth of a particle behind another "
    "fragment's surface over the run, the surface estimated continuously from that fragment's particles (a kernel "
    "volume fraction over 6 particle spacings, each particle standing for 1/n of its piece's volume, n the piece's "
    "number density measured from positions at the latch; stored particle volumes are not used). Jittered blocks "
    "pushed together by a known depth read it within 0.05Δx, also with one piece sampled twice as densely; the "
    "plane-drop bar, thinner than the kernel, reads about 0.05Δx shallow (its halves pushed by 0.1/0.2/0.3Δx "
    "read 0.05/0.16/0.26Δx), so there no particle 0.1Δx deep means none ≈ 0.15Δx deep. Particles > 0.1Δx: the "
    "most such particles in one frame; behind plane: the deepest particle behind the plane collider. Their Task "
    "Success: no particle more than 0.1Δx behind another piece's "
    "surface and none more than half a cell behind the collider (a node-based collider acts on the nodes behind "
    "the plane, so resting particles sit up to half a cell past it; the paper's plane penetration reads this)."
)


def _floor(exp: ExperimentRun) -> str:
    """Panel A's friction in words: the floor's (frictionless, the paper's, or Coulomb μ) and, where set, the
    halves' contact friction."""
    from ..config import PlaneBoundary

    cfg = exp.prepared.cfg
    planes = [b for b in cfg.sim.boundaries if isinstance(b, PlaneBoundary)]
    if planes and planes[0].mode == "friction" and planes[0].friction > 0:
        out = f"friction floor μ = {planes[0].friction:g}"
    else:
        out = "frictionless floor"
    if cfg.sim.contact.friction > 0:
        out += f", fragment contact μ = {cfg.sim.contact.friction:g}"
    return out


def _panel_a_note(exp: Optional[ExperimentRun]) -> str:
    """Why the paper's Panel A columns fail where the fragment-aware ones pass, filled from the Full run."""
    if exp is None or "full" not in exp.runs or not exp.runs["full"].rows:
        return ""
    rows = exp.runs["full"].rows
    fa = fragment_aware(rows)
    if fa["frag_pen"] is None:
        return ""
    pen = float(rows[-1].get("plane_penetration") or 0.0)
    cross = max((int(x.get("identity_crossing", 0)) for x in rows), default=0)
    if _success(pen, cross) or not fa["frag_success"]:
        return ""
    why = []
    if pen >= 0.1:
        why.append(
            f"its Pen. ({pen:.3f}Δx) is the deepest particle behind the floor, which a node-based collider lets "
            f"reach half a cell (fragment-aware: {fa['collider']:.3f}Δx, within it)"
        )
    if cross:
        why.append(
            f"its identity crossing ({cross}) counts particles past a plane of fixed normal n_Π between the band "
            f"fronts, which the bar's halves pass as they tumble and hinge about their contact with no particle "
            f"0.1Δx inside the other half (deepest particle behind the other half's surface {fa['frag_pen']:.3f}Δx)"
        )
    return " Panel A, Full fails the paper's criterion only: " + "; ".join(why) + "."


def table4(exp_a: Optional[ExperimentRun], exp_b: Optional[ExperimentRun], command: str = "") -> Table:
    """Post-fracture interaction: Panel A (fragment–plane, gravity), Panel B (fragment–fragment re-contact)."""
    panels, used = [], []
    if exp_a is not None:
        used.append(exp_a)
        cols = [
            Column("method", "Method", "Method", "text"),
            Column("tc", "t_c^0/t_c^1", r"$t_c^0/t_c^1$", "time_pair"),
            Column("pen", "Pen./Δx", r"Pen./$\Delta x$", "num"),
            Column("vt", "max abs(v_t) near plane", r"max $|v_t|$ near plane", "num"),
            Column("resid", "global residual†", r"global residual$^\dagger$", "num"),
            Column("vn", "max post-contact v_n", r"max post-contact $v_n$", "num"),
            Column("crossing", "identity crossing", "identity crossing", "int"),
            Column("success", "Task Success", "Task Success", "bool"),
        ]
        rows = []
        for v, r in exp_a.runs.items():
            rr = r.rows[-1] if r.rows else {}
            cross = max((x.get("identity_crossing", 0) for x in r.rows), default=0)
            rows.append(
                {
                    "method": variant_spec(v).label.replace("FractureFields (Full)", "Full"),
                    "tc": tuple(rr.get("plane_first_contact", [None, None])),
                    "pen": rr.get("plane_penetration"),
                    "vt": rr.get("plane_max_vt_near"),
                    "resid": rr.get("plane_momentum_residual"),
                    "vn": rr.get("plane_max_vn_post"),
                    "crossing": cross,
                    "success": _success(rr.get("plane_penetration"), cross),
                    **fragment_aware(r.rows),
                }
            )
        cols += FRAGMENT_AWARE_COLUMNS
        panels.append(Panel(cols, rows, f"Panel A: fragment–plane interaction (gravity-enabled, {_floor(exp_a)})"))
    if exp_b is not None:
        used.append(exp_b)
        cols = [
            Column("method", "Method", "Method", "text"),
            Column("t", "first-contact t", "first-contact $t$", "num"),
            Column("pen", "Pen./Δx", r"Pen./$\Delta x$", "num"),
            Column("dvt", "max abs(Δv_t)", r"max $|\Delta v_t|$", "num"),
            Column("resid", "CP mom. residual", r"CP mom.\ residual", "num"),
            Column("vn", "v_rel,n+ at contact", r"$v_{\mathrm{rel},n}^{+}$ at contact", "num"),
            Column("crossing", "identity crossing", "identity crossing", "int"),
            Column("success", "Task Success", "Task Success", "bool"),
        ]
        rows = []
        for v, r in exp_b.runs.items():
            w = [x for x in r.rows if "penetration" in x]
            last = w[-1] if w else {}
            pen = max((x["penetration"] for x in w), default=None)
            cross = max((x["identity_crossing"] for x in w), default=0)
            rows.append(
                {
                    "method": variant_spec(v).label.replace("FractureFields (Full)", "FractureFields"),
                    "t": last.get("first_contact_time"),
                    "pen": pen,
                    "dvt": last.get("max_delta_vt"),
                    "resid": last.get("cp_momentum_residual"),
                    "vn": last.get("rel_normal_velocity_after"),
                    "crossing": cross,
                    "success": _success(pen, cross),
                    **fragment_aware(r.rows),
                }
            )
        cols += FRAGMENT_AWARE_COLUMNS
        panels.append(
            Panel(cols, rows, "Panel B: controlled fragment re-contact (gravity-disabled, fragment–fragment contact)")
        )
    caption = (
        "Post-fracture interaction. Panel A: fragment–scene response under gravity; †the global residual is "
        "gravity-compensated but includes the external plane impulse (a scene-level diagnostic). Panel B: "
        "fragment–fragment re-contact without gravity. Task Success requires max penetration/Δx < 0.1 and no "
        "identity crossing (a particle on the other fragment's side of the separating plane: normal n_Π, "
        "midway between the two fragments' facing band fronts as they move; in Panel A the bar tumbles, so its "
        "band fronts along the fixed n_Π can pass each other without interpenetration). Panel-specific "
        "diagnostics must not be compared across panels."
        + FRAGMENT_AWARE_CAPTION
        + _panel_a_note(exp_a)
        + " "
        + _notes(used)
    )
    return Table(
        "table4_interaction", "Table 4: post-fracture interaction", panels, caption, "tab:scene_interaction", command
    )


def table5(exps: dict, command: str = "") -> Table:
    """Material-prior initialization: two parameter sets per scene, same protocol (variant full)."""
    cols = [
        Column("scene", "Scene", "Scene", "text"),
        Column("init", "Init.", "Init.", "text"),
        Column("E", "E", "$E$", "sci"),
        Column("rho", "ρ", r"$\rho$", "num"),
        Column("sigma_R", "σ_R", r"$\sigma_R$", "num"),
        Column("latch", "Latch", "Latch", "int"),
        Column("opening", "Opening/Δx", r"Opening/$\Delta x$", "num"),
        Column("separated", "Sep.", "Sep.", "bool"),
        Column("valid", "Valid", "Valid", "bool"),
    ]
    rows, used = [], []
    for key in ("ficus_vlm", "ficus_manual", "bread_vlm", "bread_manual"):
        exp = exps.get(key)
        if exp is None:
            continue
        used.append(exp)
        r = exp.runs["full"]
        m = exp.prepared.cfg.material
        last = r.rows[-1] if r.rows else {}
        finite = all(math.isfinite(float(x.get("kinetic_energy", 0.0))) for x in r.rows)
        rows.append(
            {
                "scene": SCENE_NAMES[exp.scene],
                "init": "VLM" if key.endswith("vlm") else "Manual",
                "E": m.E,
                "rho": m.density,
                "sigma_R": m.sigma_R,
                "latch": exp.latch_frame,
                "opening": last.get("opening"),
                "separated": last.get("separated"),
                "valid": r.status == "ok" and finite,
            }
        )
    caption = (
        "Material-prior initialization: two parameter sets per scene (VLM prior vs manual) under the same "
        "geometry, loading and fracture protocol, variant Full. Opening/Δx is the signed final opening; Valid = "
        "the rollout stayed finite to the last frame. The values are initial conditions, not recovered SI "
        "parameters; only the default material changes (bread's crust keeps its material_map values). " + _notes(used)
    )
    return Table(
        "table5_material_prior",
        "Table 5: material-prior initialization",
        [Panel(cols, rows)],
        caption,
        "tab:material_prior",
        command,
    )
