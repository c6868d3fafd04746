"""Where a captured scene's GPU memory goes: runs render-sim in-process and reports which call raised torch's
peak allocation (by more than 256 MiB), with the peak after each variant and nvidia-smi's view at the end.

    python3 benchmarks/memory.py .caps/biker.spz [frames]
"""

import functools
import subprocess
import sys

import torch

import fracture_gs.pipeline as pipeline
import fracture_gs.render_sim as runner
import fracture_gs.render_sim.job as job
import fracture_gs.render_sim.variant as variant
import fracture_gs.sim.diagnostics.tracker as diagnostics
import fracture_gs.sim.simulator as simulator
from fracture_gs.io.config import find_config, load_config
from fracture_gs.render import crack_faces

peak = {"v": 0}


def watch(owner, name):
    fn = getattr(owner, name)

    @functools.wraps(fn)
    def wrapped(*a, **k):
        out = fn(*a, **k)
        if hasattr(out, "__next__"):
            return out
        now = torch.cuda.max_memory_allocated()
        if now > peak["v"] + (256 << 20):
            print(f"peak {now / 2**30:.2f} GiB after {owner.__name__}.{name}", flush=True)
            peak["v"] = now
        return out

    setattr(owner, name, wrapped)


for owner, name in [
    (simulator.Simulator, "advance"),
    (simulator.Simulator, "diagnostics_tracker"),
    (diagnostics.Diagnostics, "snapshot"),
    (runner.Painter, "__call__"),
    (crack_faces.CrackFaces, "trimmed"),
    (crack_faces.CrackFaces, "__init__"),
    (pipeline, "frame_output"),
    (pipeline, "make_simulator"),
    (pipeline, "prepare_scene"),
]:
    watch(owner, name)
import gsplat  # noqa: E402

_raster = gsplat.rasterization


def raster(*a, **k):
    before = torch.cuda.max_memory_allocated()
    torch.cuda.reset_peak_memory_stats()
    out = _raster(*a, **k)
    used = torch.cuda.max_memory_allocated()
    if used > (2 << 30):
        meta = out[2]
        isects = int(meta["isect_ids"].numel()) if "isect_ids" in meta else -1
        radii = meta.get("radii")
        big = int((radii.float().max(-1).values > 200).sum()) if radii is not None else -1
        print(
            f"rasterization: {used / 2**30:.2f} GiB peak, {isects} tile intersections, {big} Gaussians over 200 px"
            f", N = {a[0].shape[0]}",
            flush=True,
        )
    peak["v"] = max(before, used)
    return out


gsplat.rasterization = raster
variant.make_simulator = pipeline.make_simulator  # the watched wrappers, where the job's modules call them
job.prepare_scene = pipeline.prepare_scene

cfg = load_config(find_config(sys.argv[1]))
cfg.frames = int(sys.argv[2]) if len(sys.argv) > 2 else 40
runner.run_render_sim(cfg, list(cfg.variants), "cuda:0", "/tmp/mem_run")
print(
    f"torch peak allocated {torch.cuda.max_memory_allocated() / 2**30:.2f} GiB, reserved "
    f"{torch.cuda.max_memory_reserved() / 2**30:.2f} GiB"
)
print(subprocess.run(["nvidia-smi", "--query-gpu=memory.used", "--format=csv"], capture_output=True, text=True).stdout)
