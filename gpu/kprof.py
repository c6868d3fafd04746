import sys, torch, warp as wp
sys.path.insert(0, "apps")
import bench_fragments as B
from torch.profiler import profile, ProfilerActivity
torch.cuda.set_stream(torch.cuda.Stream("cuda:0"))
cfg, P = B.state(None, "cuda:0", 128)
for K in (2, 16):
    topo = B.topology(P, K, cfg.sim.dx)
    for label, variant in B.BRANCHES:
        sim = B.build(cfg, P, topo, variant, "cuda:0")
        print(label, K, "solo", float(sim.solo.float().mean()), "cap", sim.grid.capacity, "box", sim.box)
        for _ in range(5):
            with sim._stream_scope(): sim.transfer()
        torch.cuda.synchronize()
        with profile(activities=[ProfilerActivity.CUDA]) as prof:
            with sim._stream_scope():
                for _ in range(20): sim.transfer()
            torch.cuda.synchronize()
        us = {}
        for ev in prof.events():
            name = ev.name.split("_cuda_kernel")[0]
            us[name] = us.get(name, 0.0) + ev.device_time / 20
        print("   ", {k[:40]: round(v, 1) for k, v in sorted(us.items(), key=lambda kv: -kv[1])[:8]})
