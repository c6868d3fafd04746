"""Run one experiment config over its variants (simulation, selected frames rendered) and cache the runs."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Optional, Sequence

import numpy as np
import torch

from ..config import SceneConfig
from .protocol import Prepared

# --------------------------------------------------------------------------------------------
# running experiments (simulation only; selected frames rendered)


@dataclass
class VariantRun:
    variant: str
    rows: list  # per-frame diagnostics rows (frame 0 = initial state)
    summary: dict
    status: str = "ok"
    wall_s: float = 0.0
    images: dict = field(default_factory=dict)  # frame -> HxWx3 uint8
    states: dict = field(default_factory=dict)  # frame -> dict of numpy arrays (method figure)


@dataclass
class ExperimentRun:
    name: str
    scene: str
    prepared: Prepared
    particles: int
    runs: dict  # variant -> VariantRun
    topology: Any = None
    device: str = "cpu"

    @property
    def latch_frame(self) -> Optional[int]:
        return None if self.topology is None else int(self.topology.latch_frame)

    def to_json(self) -> dict:
        c = self.prepared.cfg
        return {
            "name": self.name,
            "scene": self.scene,
            "protocol": self.prepared.protocol,
            "notes": self.prepared.notes,
            "particles": self.particles,
            "dx": c.sim.dx,
            "dt": c.sim.dt,
            "frames": c.frames,
            "frame_dt": c.frame_dt,
            "device": self.device,
            "latch_frame": self.latch_frame,
            "material": {"E": c.material.E, "density": c.material.density, "sigma_R": c.material.sigma_R},
            "variants": {
                v: {"status": r.status, "wall_s": r.wall_s, "summary": r.summary, "rows": r.rows}
                for v, r in self.runs.items()
            },
        }


def _jsonable(o):
    if torch.is_tensor(o):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))


def _clean_row(row: dict) -> dict:
    return json.loads(json.dumps(row, default=_jsonable))


def run_experiment(
    prep: Prepared,
    variants: Sequence[str],
    device: str,
    render: Optional[Callable] = None,
    render_variants: Optional[Sequence[str]] = None,
    state_frames: Callable | None = None,
    progress: bool = True,
) -> ExperimentRun:
    """Simulate each variant of `prep.cfg` (a variant with a provider first; the others replay its
    topology, as `render-sim` does) and keep every frame's diagnostics. `render(latch_frame,
    frames)` names the frames to render for the variants in `render_variants` (all if None),
    asked once the latch is known; `state_frames(sim, frame)` may capture extra data (the method
    figure's slice)."""
    from ..pipeline import load_scene, make_simulator, simulate
    from ..render_sim import Painter, summarize
    from ..sim import SimulationDiverged

    cfg = prep.cfg
    gs = load_scene(cfg, device)
    painter = Painter(gs, cfg, device) if render is not None else None
    cov0 = gs.covariances().to(device, torch.float32)
    order = sorted(variants, key=lambda v: v == "baseline")
    runs, topology = {}, None
    for variant in order:
        sim = make_simulator(cfg, gs, variant, device, topology=topology)
        rows, images, states, status = [], {}, {}, "ok"
        render_frames = set()
        if render is not None and (render_variants is None or variant in render_variants):
            render_frames = set(int(f) for f in render(None if topology is None else topology.latch_frame, cfg.frames))
        t0 = time.perf_counter()
        try:
            for out in simulate(sim, cov0, cfg.frames, cfg.frame_dt):
                rows.append(_clean_row(out.metrics))
                if out.frame in render_frames:
                    images[out.frame] = painter(out)
                if state_frames is not None:
                    s = state_frames(sim, out.frame)
                    if s is not None:
                        states[out.frame] = s
        except SimulationDiverged as err:
            status = f"diverged at frame {err.frame}"
        wall = time.perf_counter() - t0
        if sim.topology is not None and topology is None:
            topology = sim.topology
        summary = _clean_row(summarize(variant, rows, status, wall).as_dict())
        runs[variant] = VariantRun(variant, rows, summary, status, wall, images, states)
        if progress:
            latch = summary.get("latch") or {}
            print(
                f"  {cfg.name:<26s} {variant:<20s} {wall:7.1f} s  latch frame {latch.get('latch_frame')}  "
                f"opening/Δx {summary.get('opening', float('nan')):.3g}  status {status}",
                flush=True,
            )
        del sim
    return ExperimentRun(cfg.name, cfg.scene, prep, len(gs), {v: runs[v] for v in variants}, topology, device)


# --------------------------------------------------------------------------------------------
# metrics over the post-latch window


def window_rows(rows: list, latch_frame: Optional[int]) -> list:
    """Rows of the post-latch window: frames ≥ the latch frame whose diagnostics are latched."""
    if latch_frame is None:
        return []
    return [r for r in rows if r.get("latched") and r["frame"] >= latch_frame and "opening" in r]


def _mean_max(vals):
    vals = [float(v) for v in vals if v is not None]
    if not vals:
        return None
    return (float(np.mean(vals)), float(np.max(vals)))


def transfer_stats(run: VariantRun, latch_frame) -> dict:
    """Table 1 entries: mixing cf / realized mean and max, shared %, max mass residual."""
    w = window_rows(run.rows, latch_frame)
    if not w:
        return {}
    return {
        "cf": _mean_max(r["mixing_counterfactual"] for r in w),
        "real": _mean_max(r["mixing_realized"] for r in w),
        "shared": float(np.mean([r["shared_support_pct"] for r in w])),
        "mass_residual": float(max(max(r["mass_residual"]) for r in w)),
    }


def ablation_stats(run: VariantRun, latch_frame) -> dict:
    """Table 3 entries: final opening/Δx, max re-approach, mean stringing, max mass residual, separated."""
    w = window_rows(run.rows, latch_frame)
    if not w:
        return {}
    last = w[-1]
    return {
        "opening": float(last["opening"]),
        "reapproach": float(last["reapproach"]),
        "stringing": float(np.mean([r["stringing"] for r in w])),
        "mass_residual": float(max(max(r["mass_residual"]) for r in w)),
        "separated": bool(last["separated"]),
        "identity_crossing": int(max(r["identity_crossing"] for r in w)),
    }


def _physics_dict(cfg: SceneConfig) -> dict:
    """The config without its name, variant list and render settings (what decides a trajectory)."""
    from ..io.config import config_to_dict

    d = config_to_dict(cfg)
    for k in ("name", "variants", "render"):
        d.pop(k, None)
    return d


def same_physics(a: SceneConfig, b: SceneConfig) -> bool:
    return _physics_dict(a) == _physics_dict(b)


def _save_cache(exp: ExperimentRun, folder: Path) -> None:
    from ..io.video import save_png

    folder.mkdir(parents=True, exist_ok=True)
    d = exp.to_json()
    if exp.topology is not None:
        d["topology"] = {
            "point": list(exp.topology.point),
            "normal": list(exp.topology.normal),
            "latch_frame": exp.latch_frame,
            "latch_time": exp.topology.latch_time,
        }
    (folder / f"{exp.name}.json").write_text(json.dumps(d, default=_jsonable, separators=(",", ":")))
    for v, r in exp.runs.items():
        for f, img in r.images.items():
            save_png(folder / "panels" / f"{exp.name}__{v}__{f:04d}.png", img)
        if r.states:  # only the method figure's slice (the frame with the most projected nodes)
            best = max(r.states, key=lambda f: (r.states[f]["n_projected"], -f))
            (folder / f"{exp.name}__{v}__slice.json").write_text(
                json.dumps({"frame": best, **r.states[best]}, default=_jsonable)
            )


class _TopoStub:
    """The parts of a Topology the figures need, from a cached run."""

    def __init__(self, d):
        self.point, self.normal = tuple(d["point"]), tuple(d["normal"])
        self.latch_frame, self.latch_time = d["latch_frame"], d["latch_time"]


def _load_cache(key: str, prep: Prepared, folder: Path) -> Optional[ExperimentRun]:
    import cv2

    path = folder / f"{prep.cfg.name}.json"
    if not path.exists():
        return None
    d = json.loads(path.read_text())
    if d.get("protocol", d.get("preset")) != prep.protocol or d.get("particles") is None:
        return None
    runs = {}
    for v, r in d["variants"].items():
        images = {}
        for png in sorted((folder / "panels").glob(f"{prep.cfg.name}__{v}__*.png")):
            images[int(png.stem.split("__")[-1])] = cv2.imread(str(png))[..., ::-1].copy()
        states = {}
        sl = folder / f"{prep.cfg.name}__{v}__slice.json"
        if sl.exists():
            st = json.loads(sl.read_text())
            f = st["frame"]
            states[f] = {k: (np.asarray(x) if isinstance(x, list) else x) for k, x in st.items()}
        runs[v] = VariantRun(v, r["rows"], r["summary"], r["status"], r["wall_s"], images, states)
    topo = _TopoStub(d["topology"]) if d.get("topology") else None
    return ExperimentRun(d["name"], d["scene"], prep, d["particles"], runs, topo, d.get("device", "cpu"))
