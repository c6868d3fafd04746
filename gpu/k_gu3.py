"""Scratch: box_contact built up piece by piece at K = 16 (what costs)."""
import sys, torch, warp as wp
sys.path.insert(0, "apps")
import bench_fragments as bf
from torch.profiler import profile, ProfilerActivity
from fracture_gs.sim.box_kernels import (BoxView, buffer_node, node_position, normalized, box_mass_gradient,
    vec_fi, vec_f, mat_f3, box_contact)
from fracture_gs.sim.boundary import Colliders, apply_boundaries
from fracture_gs.sim.clock import Clock, clock_dt, clock_time
from fracture_gs.sim.contact import contact_normal, contact_pair
from fracture_gs.runtime import launch

wp.set_module_options({"enable_backward": False})


@wp.kernel
def k_stage(b: BoxView, eps_m: float, fill_mass: float, centroids: wp.array(dtype=wp.vec3), latched: wp.vec3,
            clock: Clock, gravity: wp.vec3, colliders: Colliders, stats: wp.array(dtype=float), stage: int):
    e = wp.tid()
    if e >= b.leaders[0]:
        return
    dt = clock_dt(clock)
    time = clock_time(clock)
    t = b.leaders[1 + e]
    node = buffer_node(b, b.box_of[t], t)
    xi = node_position(b, node)
    if stage == 0:
        b.vel[t] = normalized(b.mp[t], eps_m, dt, gravity)
        return
    idx = vec_fi(-1)
    frag = vec_fi(0)
    m = vec_f(0.0)
    V = mat_f3(0.0)
    G = mat_f3(0.0)
    n = int(0)
    i = t
    while i >= 0:
        if n < 4:
            idx[n] = i
            n += 1
        i = b.next[i]
    for a in range(n):
        ia = idx[a]
        q = b.mp[ia]
        frag[a] = b.box_of[ia]
        m[a] = q[3]
        V[a] = normalized(q, eps_m, dt, gravity)
        if stage >= 2:
            G[a] = box_mass_gradient(b, frag[a], ia, node)
    if stage >= 3:
        for a in range(n):
            for c in range(a + 1, n):
                if m[a] + m[c] >= fill_mass:
                    nrm = contact_normal(1, latched, G[a], G[c], centroids[frag[a]], centroids[frag[c]])
                    w0, w1 = contact_pair(V[a], V[c], m[a], m[c], nrm, 0.0, 0.0, 1, 0, stats, stats,
                                          frag[a], frag[c], 0, time)
                    V[a] = w0
                    V[c] = w1
    for a in range(n):
        v = V[a]
        if stage >= 4:
            v = apply_boundaries(v, node, xi, time, colliders)
        b.vel[idx[a]] = v


import os
DEV = os.environ.get("DEV", "cuda:0")
if DEV != "cpu":
    torch.cuda.set_stream(torch.cuda.Stream(DEV))
cfg, P = bf.state(None if DEV != "cpu" else 3000, DEV, 128 if DEV != "cpu" else 32)
topo = bf.topology(P, 16, cfg.sim.dx)
sim = bf.build(cfg, P, topo, "full", DEV, "cell", "boxes")
bx = sim.boxes
with sim._stream_scope():
    sim.transfer()
    sim._p2g()
    from fracture_gs.sim.box_kernels import box_grid_update
    launch(box_grid_update, bx.capacity, [bx.view, sim.eps_m, sim.clock.view, sim._gravity, sim.boundaries.colliders], DEV)
(torch.cuda.synchronize() if DEV != "cpu" else None)
L = int(bx.leaders[0])
chain = []
nxt = bx.next.cpu()
lead = bx.leaders[1:1 + L].cpu()
for t in lead.tolist()[:2000]:
    n, i = 0, t
    while i >= 0:
        n += 1; i = int(nxt[i])
    chain.append(n)
print("listed", L, "fields per node (first 2000):", torch.bincount(torch.tensor(chain)).tolist())
fill = sim.cfg.contact.fill * sim.node_mass
for stage in range(5):
    args = [bx.view, sim.eps_m, fill, sim.wp["centroids"], sim._normal, sim.clock.view, sim._gravity,
            sim.boundaries.colliders, bx._no_stats, stage]
    launch(k_stage, 16384, args, DEV)
    if DEV == "cpu":
        print("stage", stage, "ran")
        continue
    with profile(activities=[ProfilerActivity.CUDA]) as prof:
        for _ in range(20):
            with sim._stream_scope():
                launch(k_stage, 16384, args, DEV)
        (torch.cuda.synchronize() if DEV != "cpu" else None)
    us = sum(e.device_time_total for e in prof.key_averages() if "k_stage" in e.key) / 20
    print(f"stage {stage}: {us:.1f} us", flush=True)
