import cProfile, pstats, sys, torch
from fracture_gs.io.config import load_config, apply_overrides
from fracture_gs.pipeline import load_scene, make_simulator
cfg = apply_overrides(load_config("bread"), preset="paper")
gs = load_scene(cfg, "cuda:0")
sim = make_simulator(cfg, gs, "full", "cuda:0")
for f in range(3): sim.advance(cfg.frame_dt)
torch.cuda.synchronize()
pr = cProfile.Profile(); pr.enable()
for f in range(20): sim.advance(cfg.frame_dt)
torch.cuda.synchronize(); pr.disable()
pstats.Stats(pr).sort_stats("tottime").print_stats(18)
