"""Graph replay vs launches on the bread paper preset (full variant): same result, time per frame."""
import sys, time, copy, torch
from fracture_gs.io.config import load_config, apply_overrides
from fracture_gs.pipeline import load_scene, make_simulator
cfg = apply_overrides(load_config("bread"), preset="paper")
frames = int(sys.argv[1]) if len(sys.argv) > 1 else 30
gs = load_scene(cfg, "cuda:0")
res = {}
for graphs in (False, True):
    sim = make_simulator(cfg, gs, "full", "cuda:0")
    sim.use_graphs = graphs
    torch.cuda.synchronize(); t = time.perf_counter(); ts = []
    for f in range(frames):
        t0 = time.perf_counter(); sim.advance(cfg.frame_dt); torch.cuda.synchronize(); ts.append(time.perf_counter() - t0)
    res[graphs] = (sim, time.perf_counter() - t, ts)
    print(f"graphs={graphs}: {frames} frames, {sim.substeps} substeps, {res[graphs][1]:.3f} s, "
          f"median frame {1e3*sorted(ts)[len(ts)//2]:.2f} ms, latched={sim.latched}, redos={sim.frame_redos}", flush=True)
a, b = res[False][0], res[True][0]
for k in ("x", "v", "F"):
    d = (getattr(a.particles, k) - getattr(b.particles, k)).abs().max().item()
    print(k, "max |launches - graphs|", d)
