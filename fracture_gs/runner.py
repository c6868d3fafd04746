"""`fracture-gs render-sim`: simulate each variant, render it, and write videos, metrics and a summary.

Outputs in DIR: <variant>.mp4, comparison.mp4 (side by side, captions, circular fracture insets),
frames/compare_NNNN.png, metrics.jsonl, summary.json, summary.md, topology.npz, config.toml.
Ctrl-C or a divergence keeps every frame and metric already written.
"""

from __future__ import annotations

import contextlib
import copy
import json
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Literal, Optional

import numpy as np
import torch
from tqdm import tqdm

from .comparison import ComparisonVideo, compose_comparison
from .config import SceneConfig
from .energy_report import energy_markdown, energy_summary
from .io.config import dump_config
from .io.outputs import output_dir
from .io.video import VideoWriter, ffmpeg
from .pipeline import FrameOutput, make_simulator, prepare_scene, simulate
from .profiling import phases
from .render.camera import frame_camera
from .render.gaussians import exposed_interior_colors, sh_colors
from .render.splat import gsplat_needs_compile, render
from .runtime import current_lane, side_stream, stream_lane
from .sh import SH_C0
from .sim import SimulationDiverged
from .sim.diagnostics.metrics import piece_gap
from .sim.topology import save_history
from .variant_threads import run_in_threads


class Painter:
    """Per-scene render state: rest covariances, SH, visibility (interior hidden until exposed)."""

    def __init__(self, gs, cfg: SceneConfig, device: str, background=None):
        self.cfg, self.scene_cfg = cfg.render, cfg
        self.background = None
        if background is not None and len(background):  # static Gaussians outside the simulated region
            bg = background.to(device)
            self.background = (bg.means.float(), bg.covariances().float(), bg.sh.float(), bg.opacities.float())
        self.cov0 = gs.covariances().to(device, torch.float32)
        self.sh = gs.sh.to(device, torch.float32)
        self.opacities = gs.opacities.to(device, torch.float32)
        self.interior = gs.interior.to(device)
        self.surface_dc = (gs.sh[:, 0, :] * SH_C0 + 0.5).clamp(0, 1).to(device, torch.float32)
        self.exposed_rgb: Optional[torch.Tensor] = None
        self.exposed_count = 0
        self._visible_version: Optional[int] = None  # the topology version `_keep` was made for
        self._keep: Optional[torch.Tensor] = None

    def for_variant(self) -> Painter:
        """A painter for one variant's frames: the scene's tensors shared (read only), the exposed-interior
        colours its own (they follow that variant's fracture, not the previous variant's last frame)."""
        painter = copy.copy(self)
        painter.exposed_rgb, painter.exposed_count = None, 0
        painter._visible_version, painter._keep = None, None
        return painter

    def camera(self, frame: int):
        return frame_camera(self.scene_cfg, frame)

    def _visible(self, out: FrameOutput) -> torch.Tensor:
        """Indices of the Gaussians drawn: the surface, and the interior a cut has exposed. Recomputed when
        the frame's topology changed (`FrameOutput.topology_version`; −1, unknown: every frame), so a
        frame draws without reading anything back from the device."""
        version = out.topology_version
        if version < 0 or version != self._visible_version:
            exposed = self._exposed(out)
            self._keep = torch.nonzero(~self.interior | exposed).flatten()
            self._visible_version = version
        return self._keep

    def _exposed(self, out: FrameOutput) -> torch.Tensor:
        if not self.cfg.show_exposed_interior or not bool((out.fragment >= 0).any()):
            return torch.zeros_like(self.interior)
        exposed = self.interior & (out.band != 0)
        count = int(exposed.sum())
        material = self.cfg.interior_color == "material"
        if count != self.exposed_count and count > 0 and (material or bool((~self.interior).any())):
            # computed when a fracture exposes new interior: the material's own colour, or the nearest surface's
            if material:
                rgb = torch.tensor(self.cfg.interior_rgb, dtype=torch.float32, device=out.means.device)
                self.exposed_rgb = rgb.expand(count, 3)
            else:
                self.exposed_rgb = exposed_interior_colors(
                    out.means[exposed], out.means[~self.interior], self.surface_dc[~self.interior]
                )
            self.exposed_idx = torch.nonzero(exposed).flatten()
            self.exposed_count = count
        return exposed

    def _fragment_colors(self, colors: torch.Tensor, fragment: torch.Tensor) -> torch.Tensor:  # [N,3] -> [N,3]
        """Each fragment in its own hue (golden-ratio spacing), shaded by the Gaussian's own brightness."""
        k = fragment.clamp_min(0).to(torch.float32)
        hue = torch.remainder(0.61803398875 * k + 0.08, 1.0)
        phase = torch.arange(3, device=k.device, dtype=torch.float32) / 3  # [0, 1/3, 2/3], no host copy
        rgb = 0.5 + 0.45 * torch.cos(2 * torch.pi * (hue[:, None] + phase))
        shade = 0.55 + 0.45 * colors.mean(1, keepdim=True).clamp(0, 1)
        return torch.where((fragment >= 0)[:, None], rgb * shade, colors)

    def __call__(self, out: FrameOutput) -> np.ndarray:
        cam = self.camera(out.frame)
        keep = self._visible(out)  # [M] indices
        colors = sh_colors(self.sh, out.means, cam.campos.to(out.means), out.rotations)
        if self.exposed_rgb is not None:
            colors[self.exposed_idx] = self.exposed_rgb
        if self.cfg.color_by == "fragment":
            colors = self._fragment_colors(colors, out.fragment)
        means, covars, colors, opacities = (
            t.index_select(0, keep) for t in (out.means, out.covars, colors, self.opacities)
        )
        if self.background is not None:
            bm, bc, bsh, bo = self.background
            bcol = sh_colors(bsh, bm, cam.campos.to(bm))
            means, covars = torch.cat([means, bm]), torch.cat([covars, bc])
            colors, opacities = torch.cat([colors, bcol]), torch.cat([opacities, bo])
        img = render(
            means,
            covars,
            colors,
            opacities,
            cam.to(out.means.device),
            background=self.cfg.background,
            backend=self.cfg.backend,
            mode=self.cfg.mode,
        ).image
        return (img.clamp(0, 1) * 255).round().to(torch.uint8).cpu().numpy()


def _post(rows: list, key: str):
    vals = [r[key] for r in rows if r.get(key) is not None]
    return vals


def summarize(variant: str, rows: list, status: str, seconds: float) -> dict:
    """Run-level numbers: final opening, max re-approach, mean stringing after the latch, mixing
    mean/max, max mass residual, contact metrics, penetration max, speed, energy (`energy_report`)."""
    post = [r for r in rows if r.get("latched")]
    out = {
        "variant": variant,
        "status": status,
        "frames": rows[-1]["frame"] if rows else 0,
        "substeps": rows[-1]["substeps"] if rows else 0,
        "wall_s": round(seconds, 3),
    }
    out["substeps_per_s"] = round(out["substeps"] / seconds, 2) if seconds > 0 else None
    latch = next((r["latch"] for r in rows if "latch" in r), None)
    out["latch"] = latch
    out["energy"] = energy_summary(rows)
    if post:
        last = post[-1]
        for k in ("mixing_counterfactual", "mixing_realized"):
            vals = _post(post, k)
            out[k + "_mean"], out[k + "_max"] = float(np.mean(vals)), float(np.max(vals))
        out["shared_support_pct_mean"] = float(np.mean(_post(post, "shared_support_pct")))
        out["mass_residual_max"] = float(max(max(r["mass_residual"]) for r in post))
        out["opening"] = last["opening"]
        out["separated"] = bool(last["separated"])
        out["reapproach"] = last["reapproach"]
        out["stringing"] = float(np.mean(_post(post, "stringing")))
        out["penetration_max"] = float(max(_post(post, "penetration")))
        out["identity_crossing_max"] = int(max(_post(post, "identity_crossing")))
        out["fragments"] = int(max(_post(post, "fragments") or [2]))
        out["fragment_crossing_max"] = int(max(_post(post, "fragment_crossing") or [0]))
        out["fragment_penetration_max"] = float(max(_post(post, "fragment_penetration") or [0.0]))
        out["collider_crossing_max"] = int(max(_post(post, "collider_crossing") or [0]))
        out["slot_overflow"] = int(sum(_post(post, "slot_overflow")))
        for k in ("first_contact_time", "cp_momentum_residual", "rel_normal_velocity_after", "max_delta_vt"):
            out[k] = last.get(k)
    if rows and "plane_penetration" in rows[-1]:
        last = rows[-1]
        for k in (
            "plane_first_contact",
            "plane_penetration",
            "plane_max_vt_near",
            "plane_max_vn_post",
            "plane_momentum_residual",
        ):
            out[k] = last[k]
    return out


def summary_markdown(summaries: list) -> str:
    cols = [
        ("variant", "variant"),
        ("status", "status"),
        ("latch frame", None),
        ("opening/Δx", "opening"),
        ("re-approach", "reapproach"),
        ("stringing", "stringing"),
        ("separated", "separated"),
        ("E_mix cf mean", "mixing_counterfactual_mean"),
        ("E_mix real mean", "mixing_realized_mean"),
        ("max E_m", "mass_residual_max"),
        ("pen./Δx", "penetration_max"),
        ("fragments", "fragments"),
        ("fragment crossing", "fragment_crossing_max"),
        ("slot overflow", "slot_overflow"),
        ("substeps/s", "substeps_per_s"),
    ]

    def fmt(v):
        if v is None:
            return "—"
        if isinstance(v, bool):
            return "yes" if v else "no"
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)

    lines = ["| " + " | ".join(c for c, _ in cols) + " |", "|" + "---|" * len(cols)]
    for s in summaries:
        cells = [fmt(s.get(k)) if k else fmt((s.get("latch") or {}).get("latch_frame")) for _, k in cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


class FrameSink:
    """Renders, encodes and keeps the frames of one variant on a worker thread, so frame n is drawn
    while the solver runs frame n + 1 (Warp's and torch's kernels release the GIL). A bounded queue
    keeps at most two frames in flight; an error on the worker is raised in the caller at the next
    `put` or at `close`. Closing always drains what was queued (Ctrl-C and divergences keep every
    frame simulated so far)."""

    def __init__(self, painter: Painter, video_path: Path, fps: int, store: list):
        self.painter, self.store = painter, store
        self.video = VideoWriter(video_path, fps=fps)
        self.error: Optional[BaseException] = None
        self.queue: queue.Queue = queue.Queue(maxsize=2)
        self.lane = current_lane()  # the producer's stream lane: variant threads draw on their own streams
        self.thread = threading.Thread(target=self._work, name="fgs-render", daemon=True)
        self.thread.start()

    def _work(self) -> None:
        with stream_lane(self.lane):
            self._drain()

    def _drain(self) -> None:
        while True:
            out = self.queue.get()
            if out is None:
                return
            if self.error is not None:
                continue
            try:
                with phases.section("render"), self._on_render_stream(out):
                    img = self.painter(out)
                with phases.section("encode"):
                    self.video.write(img)
                self.store.append(img)
            except BaseException as exc:  # noqa: BLE001 - handed to the caller
                self.error = exc

    @staticmethod
    def _on_render_stream(out: FrameOutput):
        """On CUDA, draw on the render stream once the producer's copies of the frame are done (the event
        `put` recorded), and keep those tensors' memory from reuse until the render stream is past them."""
        if out.ready is None:
            return contextlib.nullcontext()
        stream = side_stream(out.means.device, "render")
        stream.wait_event(out.ready)
        for t in (out.means, out.F, out.fragment, out.band):
            t.record_stream(stream)
        return torch.cuda.stream(stream)

    def put(self, out: FrameOutput) -> None:
        if self.error is not None:
            raise self.error
        if out.means.is_cuda:
            out.ready = torch.cuda.Event()
            out.ready.record(torch.cuda.current_stream(out.means.device))
        self.queue.put(out)

    def close(self) -> None:
        self.queue.put(None)
        self.thread.join()
        with phases.section("encode"):
            self.video.close()
        if self.error is not None:
            raise self.error


def run_variant(
    cfg,
    gs,
    variant,
    device,
    out_dir: Path,
    painter: Painter,
    topology,
    metrics_file,
    frames_store: list,
    export=None,
    provider=None,
    stop=None,
    position: int = 0,
):
    """Simulate + render one variant; appends frames to `frames_store`; returns (summary, topology).
    `export`: (every N frames, Capture, format) to write the frames as splat files in the scene's frame. `provider`:
    the event provider to use instead of the config's or the replayed topology's; `stop`: a
    threading or multiprocessing Event that interrupts the variant at its next frame (as Ctrl-C does)."""
    sim = make_simulator(cfg, gs, variant, device, topology=topology, provider=provider)
    rows, status, t0 = [], "ok", time.perf_counter()
    bar = progress_bar(cfg.frames, f"{variant:>20s}", position)
    sink = FrameSink(painter.for_variant(), out_dir / f"{variant}.mp4", cfg.render.fps, frames_store)
    interrupted = False
    try:
        for out in simulate(
            sim,
            painter.cov0,
            cfg.frames,
            cfg.frame_dt,
            carrier=gs.carrier,
            crack_faces=cfg.render.trim_cracks,
            max_stretch=cfg.render.max_stretch,
        ):
            with phases.section("io"):
                metrics_file.write(json.dumps({"variant": variant, **out.metrics}, default=_json_default) + "\n")
                metrics_file.flush()
            rows.append(out.metrics)
            if stop is not None and stop.is_set():
                raise KeyboardInterrupt
            if export is not None and out.frame % export[0] == 0:
                with phases.section("io"):
                    _export(out, painter, export, out_dir / "ply" / variant, f"frame_{out.frame:04d}")
            sink.put(out)
            if out.frame > 0:
                elapsed = time.perf_counter() - t0
                bar.set_postfix(
                    substeps_per_s=f"{sim.substeps / elapsed:.0f}",
                    fragments=sim.n_fragments,
                    overflow=sim.slot_overflow_total,
                    refresh=False,
                )
                bar.update(1)
    except SimulationDiverged as err:
        status = f"diverged at frame {err.frame}: {err.cause}"
        tqdm.write(f"{variant}: {err}")
        metrics_file.write(json.dumps({"variant": variant, "frame": err.frame, "diverged": str(err)}) + "\n")
    except KeyboardInterrupt:
        interrupted = True
        status = f"interrupted at frame {rows[-1]['frame'] if rows else 0}"
    finally:
        bar.close()
        sink.close()
    if sim.topologies and topology is None:
        topology = list(sim.topologies)
    summary = summarize(variant, rows, status, time.perf_counter() - t0)
    summary["piece_gap"] = piece_gap(sim.particles.x, sim.particles.fragment, sim.grid.dx)
    summary["interrupted"] = interrupted
    return summary, topology


def _export(out: FrameOutput, painter: Painter, export: tuple, folder: Path, stem: str) -> None:
    """One frame to folder/stem + the format's suffix; export = (every N frames, Capture, format)."""
    from .capture.export import export_ply, frame_gaussians
    from .io.formats import SUFFIX

    _, cap, fmt = export
    drawn = ~painter.interior | painter._exposed(out)
    gs = frame_gaussians(cap.gaussians, out.means, out.covars, out.rotations, drawn)
    to_scene = cap.transform.inverse() if cap.transform is not None else None
    export_ply(folder / f"{stem}{SUFFIX[fmt]}", gs, cap.background, to_scene, fmt)


def progress_bar(total: int, desc: str, position: int = 0) -> tqdm:
    """A tqdm bar; in a non-interactive log (stderr not a terminal) it prints a line every few
    seconds instead of every update."""
    interactive = sys.stderr.isatty()
    return tqdm(
        total=total,
        desc=desc,
        position=position,
        unit="frame",
        leave=True,
        dynamic_ncols=True,
        mininterval=0.1 if interactive else 5.0,
        maxinterval=10.0 if interactive else 30.0,
    )


def _json_default(o):
    if torch.is_tensor(o):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o))


def _run_in_turn(cfg, gs, order, device, out_dir, painter, metrics_file, export, variants, stop=None):
    """The variants one after the other on one device; the first's topology is replayed by the rest.
    While the last one runs, the comparison video (panels in `variants` order) is composed beside it
    when the others all have frames and the topology is known; returns that `ComparisonVideo` (or None)."""
    frames, summaries, topology, interrupted, live = {}, {}, None, False, None
    try:
        for k, variant in enumerate(order):
            if stop is not None and stop.is_set():
                interrupted = True
                break
            frames[variant] = []
            if k > 0 and k == len(order) - 1 and topology is not None and all(frames[v] for v in order[:k]):
                statuses = [summaries[v]["status"] if v in summaries else "ok" for v in variants]
                panels = [frames[v] for v in variants]
                live = ComparisonVideo(cfg, variants, panels, topology, out_dir, statuses)
                live.start_live(frames[variant])
            summaries[variant], topology = run_variant(
                cfg, gs, variant, device, out_dir, painter, topology, metrics_file, frames[variant], export, stop=stop
            )
            if topology is not None and not (out_dir / "topology.npz").exists():
                save_history(out_dir / "topology.npz", topology)
            if summaries[variant]["interrupted"]:
                interrupted = True
                break
    except KeyboardInterrupt:  # between variants
        interrupted = True
    except BaseException:
        if live is not None:
            live.abort()
        raise
    return frames, summaries, topology, interrupted, live


def _run_in_threads(cfg, gs, order, device, out_dir, painter, metrics_file, export, variants, stop=None):
    """The variants at once on one device, a thread each (`fracture_gs.variant_threads`); the comparison video
    is composed beside them from the leader's first latch. Returns what `_run_in_turn` returns."""
    live = None

    def first_latch(topology, frames) -> None:
        nonlocal live
        panels = [frames[v] for v in variants]
        live = ComparisonVideo(cfg, variants, panels, topology, out_dir, ["ok"] * len(variants))
        live.start_live(*panels)

    try:
        frames, summaries, topology, interrupted = run_in_threads(
            run_variant, painter, cfg, gs, order, device, out_dir, metrics_file, export, stop, first_latch
        )
    except BaseException:
        if live is not None:
            live.abort()
        raise
    if topology is not None:
        save_history(out_dir / "topology.npz", topology)
    return frames, summaries, topology, interrupted, live


def _threads(schedule: str) -> bool:
    if schedule not in ("in_turn", "threads"):
        raise ValueError(f"schedule must be 'in_turn' or 'threads', got {schedule!r}")
    return schedule == "threads"


def run_render_sim(
    cfg: SceneConfig,
    variants,
    device: str,
    out_dir,
    progress: bool = True,
    profile: bool = False,
    export_ply: Optional[int] = None,
    export_format: str = "ply",
    devices: Optional[list] = None,
    stop=None,
    schedule: Literal["in_turn", "threads"] = "in_turn",
) -> dict:
    """The main job. Returns the summary dict (also written to summary.json / summary.md); with
    `profile`, the time per phase is in summary["profile"] and profile.md; with `export_ply` = N, every
    N-th frame of every variant also goes to ply/<variant>/frame_NNNN.<suffix> in `export_format` (ply,
    compressed-ply, splat or spz: `io.formats.write_gaussians`; the scene's frame).
    A captured PLY scene is resolved first (capture.resolve): config.toml is the resolved config. With
    `devices` (several), the variants run side by side, one per device (`fracture_gs.parallel`). On one device
    `schedule` says how: "in_turn", one after the other; "threads", at once, a thread each
    (`fracture_gs.variant_threads`: the same outputs, metrics.jsonl's rows interleaved).
    `stop`: a threading Event that interrupts the run at the next frame, like Ctrl-C (the CLI sets it
    from its SIGINT handler, so an interrupt Python drops inside a finalizer still stops the run; with
    `devices` the worker processes stop on Ctrl-C themselves and the event only marks the summary)."""
    out_dir = output_dir(out_dir)
    ffmpeg()  # a missing video encoder is one sentence now, not after the scene is prepared and simulated
    if profile:
        phases.enable(sync_device=device if device.startswith("cuda") else None)
    if device.startswith("cuda") and cfg.render.backend != "torch" and gsplat_needs_compile():
        tqdm.write("compiling gsplat's CUDA kernels once, about a minute (cached for later runs) ...")
    with phases.section("setup"):
        scene = prepare_scene(cfg, device)
        cfg, gs = scene.cfg, scene.gaussians
        for note in scene.notes:
            tqdm.write(f"{cfg.name}: {note}")
        painter = Painter(gs, cfg, device, background=scene.background)
    (out_dir / "config.toml").write_text(dump_config(cfg))
    export = (int(export_ply), scene, export_format) if export_ply else None
    # a variant with a provider runs first; its latched topology is replayed by all the others
    order = sorted(variants, key=lambda v: v == "baseline")
    with open(out_dir / "metrics.jsonl", "w") as metrics_file:
        if devices and len(devices) > 1:
            from .parallel import run_on_devices

            frames, summaries, topology, interrupted = run_on_devices(
                run_variant, Painter, cfg, gs, scene.background, order, list(devices), out_dir, metrics_file, export
            )
            live = None
            if topology is not None:
                save_history(out_dir / "topology.npz", topology)
        elif _threads(schedule) and len(order) > 1:
            frames, summaries, topology, interrupted, live = _run_in_threads(
                cfg, gs, order, device, out_dir, painter, metrics_file, export, list(variants), stop
            )
        else:
            frames, summaries, topology, interrupted, live = _run_in_turn(
                cfg, gs, order, device, out_dir, painter, metrics_file, export, list(variants), stop
            )
    done = [v for v in variants if v in summaries and frames[v]]
    statuses = [summaries[v]["status"] for v in done]
    if live is not None and done == live.variants:
        live.finish(statuses)
    else:
        if live is not None:  # a variant ended with no frame: compose the ones that have frames
            live.abort()
        if done:
            compose_comparison(cfg, done, [frames[v] for v in done], topology, out_dir, statuses)
    interrupted = interrupted or (stop is not None and stop.is_set())
    summary = {
        "name": cfg.name,
        "scene": cfg.scene,
        "preset": cfg.preset,
        "device": device,
        "particles": len(gs),
        "capture": scene.notes,
        "frames": cfg.frames,
        "frame_dt": cfg.frame_dt,
        "variants": [
            summaries.get(v) or {"variant": v, "status": "not run (interrupted before it)", "interrupted": True}
            for v in variants
        ],
        "interrupted": interrupted,
        "out_dir": str(out_dir),
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2, default=_json_default))
    (out_dir / "summary.md").write_text(
        f"# {cfg.name}: {cfg.scene} ({cfg.preset}, {len(gs)} particles, {device})\n\n"
        + summary_markdown(summary["variants"])
        + energy_markdown(summary["variants"])
    )
    if profile:
        summary["profile"] = phases.report()
        (out_dir / "profile.md").write_text(f"# where the time went: {cfg.name} ({device})\n\n" + summary["profile"])
        phases.disable()
    if interrupted:
        raise KeyboardInterrupt(f"interrupted; partial outputs (frames, metrics, videos so far) are in {out_dir}")
    return summary
