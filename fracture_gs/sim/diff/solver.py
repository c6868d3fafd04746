"""`DiffSimulator`: MLS-MPM frames as torch autograd operations (gradients through the simulation).

One frame is one `torch.autograd.Function`: its forward runs the frame's substeps with the
differentiable kernels (no tape, nothing kept but the frame's input state: one checkpoint per
frame), its backward runs them again under a `wp.Tape` with a fresh buffer per substep and
propagates the adjoints to the frame's input state (x, v, C, F) and parameters (μ, λ, mass, V⁰).
Memory therefore grows with frames (one state per frame) but not with substeps (one frame's
substeps at a time).

Conventions (docs/DESIGN.md "Differentiable simulation"): the frame's Δt and substep count are fixed
by the forward pass (no gradient through the CFL choice); fracture events are discrete, so the
topology (fragment ids, band) is held fixed at each frame as latched, and gradients flow through each
fragment's own dynamics on both sides of a latch, as through a fixed contact set. Supported: fixed-
corotated and neo-Hookean materials, every variant but the global fragment pass, plane, cuboid and
sphere boundaries (up to `kernels.MAX_BOUNDARIES` of each) and domain walls, fragment contact with the
latched normal (restitution, friction).
"""

from __future__ import annotations

import contextlib
import gc
import math
from dataclasses import dataclass
from typing import Optional

import torch
import warp as wp

from ...config import SimConfig
from ...errors import SimulationError
from ...runtime import ensure_warp, torch_stream
from ...variants import variant_spec
from ..grid.domain import fit_grid
from ..physics.boundary import Boundaries
from ..physics.constitutive import MATERIAL_IDS
from . import kernels as K

DIFF_MATERIALS = ("fixed_corotated", "neo_hookean")
MAX_FIELDS = 8


@dataclass
class FramePlan:
    """What the forward pass decided for one frame (replayed exactly by the backward pass)."""

    n: int  # substeps
    dt: float  # substep [s]
    t0: float  # time at the frame's start [s]
    field: torch.Tensor  # [N] int32 routed field per particle
    released: torch.Tensor  # [N] float32 1 − γ_p for released band particles, else 1
    band: torch.Tensor  # [N] float32 γ_p for the contact gate
    fields: int  # K
    lo: tuple = (0, 0, 0)  # the frame's fields cover grid nodes [lo, lo + shape)
    shape: tuple = (0, 0, 0)


class DiffSimulator:
    """Differentiable frames of the solver configured by `cfg` (a SimConfig) on a fixed grid.

    `x0` [N, 3] fixes the grid (as the plain Simulator would fit it); `material` is a model name or
    [N] ids; `topologies` is a list of Topology snapshots (e.g. from a plain run) replayed at their
    latch frames. `wave_speed` [m/s]: the stiffest material's elastic wave speed √((λ + 2μ)/ρ), added to the
    fastest particle's speed in the adaptive CFL bound (0, the default: the particles' speed alone)."""

    def __init__(
        self,
        cfg: SimConfig,
        x0: torch.Tensor,
        device: str = "cpu",
        material="fixed_corotated",
        topologies: Optional[list] = None,
        wave_speed: float = 0.0,
    ):
        ensure_warp()
        self.cfg, self.device = cfg, str(device)
        if self.device.startswith("cuda"):
            _keep_tape_memory(self.device, x0.shape[0])
        self.spec = variant_spec(cfg.variant)
        if self.spec.per_fragment_pass:
            raise SimulationError(
                "sim.variant = 'global_fragment_pass' is not differentiable; use local_multifield or full"
            )
        n = x0.shape[0]
        ids = (
            torch.full((n,), MATERIAL_IDS[material], dtype=torch.int32)
            if isinstance(material, str)
            else torch.as_tensor(material, dtype=torch.int32)
        )
        if bool((ids > 1).any()):
            raise SimulationError(f"only {', '.join(DIFF_MATERIALS)} are differentiable; plasticity is not yet")
        self.material = ids.to(self.device).contiguous()
        self.boundaries = Boundaries(cfg.boundaries, self.device, (1, 1, 1), cfg.wall_cells)
        if self.boundaries.regions:
            raise SimulationError('timed particle regions (sim.boundaries type = "region") are not differentiable yet')
        for kind, key in (("plane", "plane_point"), ("cuboid", "box_lower"), ("sphere", "sphere_radius")):
            if self.boundaries.t[key].shape[0] > K.MAX_BOUNDARIES:
                raise SimulationError(
                    f'sim.boundaries: the differentiable solver takes at most {K.MAX_BOUNDARIES} of type = "{kind}" '
                    f"(got {self.boundaries.t[key].shape[0]}); merge or remove some"
                )
        self.origin, self.dx, self.shape = fit_grid(cfg, x0.detach())
        self.boundaries = Boundaries(cfg.boundaries, self.device, self.shape, cfg.wall_cells)
        self.n_nodes = self.shape[0] * self.shape[1] * self.shape[2]
        lo = [o + (cfg.wall_cells - 1) * self.dx for o in self.origin]
        hi = [o + (s - cfg.wall_cells) * self.dx for o, s in zip(self.origin, self.shape)]
        self._lower, self._upper = wp.vec3(*lo), wp.vec3(*hi)
        self.topologies = sorted(topologies or [], key=lambda t: t.latch_frame)
        self.wave_speed = wave_speed
        self.time = 0.0
        self.frame = 0
        self.plans: list[FramePlan] = []

    # ---- per frame ---------------------------------------------------------------------------
    def topology_at(self, frame: int):
        """The latest snapshot latched at or before the end of `frame` − 1 (None before any latch)."""
        out = None
        for t in self.topologies:
            if t.latch_frame <= frame:
                out = t
        return out

    def plan(self, frame: int, v: torch.Tensor, frame_dt: float, node_mass: float) -> FramePlan:
        """Substeps and routing of `frame` (host decisions, made once in the forward pass)."""
        cfg = self.cfg
        dt = cfg.dt
        if cfg.adaptive_dt:
            speed = float(v.detach().norm(dim=1).max()) + self.wave_speed  # [m/s]
            if speed > 0:  # at rest with no wave speed given nothing bounds Δt but cfg.dt
                dt = min(dt, cfg.cfl * self.dx / speed)
        n = max(1, math.ceil(frame_dt / dt - 1e-9))
        topo = self.topology_at(frame)
        N = v.shape[0]
        if topo is None:
            field = torch.zeros(N, dtype=torch.int32, device=self.device)
            band = torch.zeros(N, dtype=torch.float32, device=self.device)
            released = torch.ones(N, dtype=torch.float32, device=self.device)
            fields = 1
        else:
            frag = topo.fragment.to(self.device).long()
            fields = int(frag.max()) + 1 if self.spec.multifield else 1
            if fields > MAX_FIELDS:
                raise SimulationError(
                    f"the differentiable path holds up to {MAX_FIELDS} fragments; this run has {fields}"
                )
            field = (frag if self.spec.multifield else torch.zeros_like(frag)).to(torch.int32)
            b = topo.band.to(self.device)
            band = (b != 0).float()
            rel = (b != 0) & (b <= topo.release_events) if self.spec.release else torch.zeros_like(b, dtype=torch.bool)
            released = (~rel).float()
        lo, shape = self._box(v, frame_dt)
        return FramePlan(
            n, frame_dt / n, self.time, field.contiguous(), released.contiguous(), band.contiguous(), fields, lo, shape
        )

    def _box(self, v: torch.Tensor, frame_dt: float) -> tuple[tuple, tuple]:
        """Grid nodes the frame's particles can reach: their bounding box plus the stencil, twice their
        travel (speed and gravity) and two spare cells, inside the grid (the plain solver's active box)."""
        x = self._x.detach()
        lo_w, hi_w = x.min(0).values.double().cpu(), x.max(0).values.double().cpu()
        vmax = float(v.detach().norm(dim=1).max())
        g = math.sqrt(sum(float(a) ** 2 for a in self.cfg.gravity))
        pad = 5 + math.ceil(2 * (vmax * frame_dt + 0.5 * g * frame_dt**2) / self.dx)
        lo = tuple(max(0, int(math.floor((float(lo_w[a]) - o) / self.dx)) - pad) for a, o in enumerate(self.origin))
        hi = tuple(
            min(s, int(math.floor((float(hi_w[a]) - o) / self.dx)) + 1 + pad)
            for a, (o, s) in enumerate(zip(self.origin, self.shape))
        )
        return lo, tuple(h - l for l, h in zip(lo, hi))  # noqa: E741

    def substeps(self, p: FramePlan, state: list, params: list, record: bool) -> list:
        """Run a frame's substeps from `state` = [x, v, C, F] (Warp arrays); returns the final state.
        With `record`, every substep writes fresh arrays (the tape needs each intermediate)."""
        x, v, C, F = state
        mu, lam, mass, volume = params
        N = x.shape[0]
        kw = dict(device=self.device, requires_grad=record)
        field, band, released = (wp.from_torch(t) for t in (p.field, p.band, p.released))
        nodes = p.shape[0] * p.shape[1] * p.shape[2]
        KN = p.fields * nodes
        cfg = self.cfg
        eps_m, eps_b = self.eps
        g = wp.vec3(*[float(a) for a in cfg.gravity])
        origin = wp.vec3(*[o + i * self.dx for o, i in zip(self.origin, p.lo)])
        shape, lo = wp.vec3i(*p.shape), wp.vec3i(*p.lo)
        normal = wp.vec3(*self._normal(p))
        for i in range(p.n):
            t = p.t0 + i * p.dt
            tau = wp.zeros(N, dtype=wp.mat33, **kw)
            wp.launch(K.stress, dim=N, inputs=[F, self.material, mu, lam, released], outputs=[tau], device=self.device)
            gm, gb = wp.zeros(KN, dtype=float, **kw), wp.zeros(KN, dtype=float, **kw)
            gp = wp.zeros(KN, dtype=wp.vec3, **kw)
            wp.launch(
                K.p2g,
                dim=N,
                inputs=[x, v, C, tau, mass, volume, field, band, p.dt, origin, self.dx, 1.0 / self.dx, shape],
                outputs=[gm, gp, gb],
                device=self.device,
            )
            gv = wp.zeros(KN, dtype=wp.vec3, **kw)
            wp.launch(K.normalize, dim=KN, inputs=[gm, gp, eps_m, p.dt, g], outputs=[gv], device=self.device)
            if self.spec.contact and p.fields > 1:
                for a in range(p.fields):
                    for b in range(a + 1, p.fields):
                        out = wp.zeros(KN, dtype=wp.vec3, **kw)
                        wp.launch(
                            K.contact_pair,
                            dim=nodes,
                            inputs=[
                                gm,
                                gb,
                                gv,
                                a,
                                b,
                                nodes,
                                p.fields,
                                normal,
                                eps_m,
                                eps_b,
                                float(cfg.restitution),
                                float(cfg.contact.friction),
                            ],
                            outputs=[out],
                            device=self.device,
                        )
                        gv = out
            gvb = wp.zeros(KN, dtype=wp.vec3, **kw)
            wp.launch(
                K.boundaries,
                dim=KN,
                inputs=[gm, gv, eps_m, origin, self.dx, shape, lo, t, self.boundaries.colliders],
                outputs=[gvb],
                device=self.device,
            )
            x1, v1 = wp.zeros(N, dtype=wp.vec3, **kw), wp.zeros(N, dtype=wp.vec3, **kw)
            C1, F1 = wp.zeros(N, dtype=wp.mat33, **kw), wp.zeros(N, dtype=wp.mat33, **kw)
            wp.launch(
                K.g2p,
                dim=N,
                inputs=[x, F, field, gvb, p.dt, origin, self.dx, 1.0 / self.dx, shape, self._lower, self._upper],
                outputs=[x1, v1, C1, F1],
                device=self.device,
            )
            x, v, C, F = x1, v1, C1, F1
        return [x, v, C, F]

    def _normal(self, p: FramePlan) -> tuple:
        if not self.topologies:
            return (1.0, 0.0, 0.0)
        n = torch.tensor(self.topologies[0].normal, dtype=torch.float64)
        return tuple(float(a) for a in n / n.norm())

    # ---- the autograd frame ----------------------------------------------------------------------
    def step(self, frame_dt: float, x, v, C, F, mu, lam, mass, volume):
        """Advance one frame; every argument a torch tensor ([N,3], [N,3], [N,3,3], [N,3,3], [N] × 4),
        every output differentiable with respect to every input."""
        if not self.plans:
            node = float(mass.detach().sum() / volume.detach().sum()) * self.dx**3
            self.eps = (self.cfg.eps_mass * node, self.cfg.eps_band * node)
        self._x = x
        plan = self.plan(self.frame, v, frame_dt, 0.0)
        self.plans.append(plan)
        out = _Frame.apply(self, plan, x, v, C, F, mu, lam, mass, volume)
        self.time += frame_dt
        self.frame += 1
        return out


# freed memory Warp's pool keeps per particle: the measured peak of a recorded frame is 7 KiB per particle
# (K = 2), but its reserve grows past the peak with fragmentation; 16 KiB still let passes re-allocate
# (backward 2.4-3.3x forward), 48 KiB did not (1.9x)
TAPE_BYTES_PER_PARTICLE = 48 << 10


def _keep_tape_memory(device: str, n: int) -> None:
    """Let Warp's CUDA pool keep a recorded frame's worth of freed memory. Above its release threshold the
    pool hands freed blocks back to the driver, so every backward pass re-allocated each substep's
    buffers from the driver: with the memory kept the backward/forward ratio is steady, without it it
    swung widely and single passes stalled (ficus, 171,553 particles; BENCHMARKS.md, "Gradients"). Only
    ever raises the threshold."""
    if wp.is_mempool_enabled(device) and wp.get_mempool_release_threshold(device) < TAPE_BYTES_PER_PARTICLE * n:
        wp.set_mempool_release_threshold(device, TAPE_BYTES_PER_PARTICLE * n)


@contextlib.contextmanager
def _gc_paused():
    """Python's cyclic collector held off while a frame's tape is recorded and replayed: the tape
    creates thousands of short-lived array objects, and a full collection in the middle stalled single
    backward passes by several times their length on a GPU (docs/benchmarks/history-2026-11.md, issue 15)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _wp(t: torch.Tensor, requires_grad: bool):
    """A Warp array over a float32 copy of torch tensor t ([N], [N,3] or [N,3,3])."""
    t = t.detach().to(torch.float32).contiguous().clone()
    dtype = {1: wp.float32, 2: wp.vec3, 3: wp.mat33}[t.dim()]
    return wp.from_torch(t, dtype=dtype, requires_grad=requires_grad)


def _torch(a, shape) -> torch.Tensor:
    return wp.to_torch(a).reshape(shape).clone()


class _Frame(torch.autograd.Function):
    """One frame of substeps; backward recomputes them under a wp.Tape (one checkpoint per frame)."""

    @staticmethod
    def forward(ctx, sim: DiffSimulator, plan: FramePlan, x, v, C, F, mu, lam, mass, volume):
        ctx.sim, ctx.plan = sim, plan
        ctx.save_for_backward(x, v, C, F, mu, lam, mass, volume)
        with torch_stream(sim.device):
            state = [_wp(t, False) for t in (x, v, C, F)]
            params = [_wp(t, False) for t in (mu, lam, mass, volume)]
            out = sim.substeps(plan, state, params, record=False)
        return tuple(_torch(a, t.shape).to(t.dtype) for a, t in zip(out, (x, v, C, F)))

    @staticmethod
    def backward(ctx, gx, gv, gC, gF):
        sim, plan = ctx.sim, ctx.plan
        inputs = ctx.saved_tensors
        with torch_stream(sim.device), _gc_paused():
            state = [_wp(t, True) for t in inputs[:4]]
            params = [_wp(t, True) for t in inputs[4:]]
            tape = wp.Tape()
            with tape:
                out = sim.substeps(plan, state, params, record=True)
            grads = {}
            for a, g in zip(out, (gx, gv, gC, gF)):
                if g is not None:
                    grads[a] = _wp(g, False)
            tape.backward(grads=grads)
            adj = [_torch(a.grad, t.shape).to(t.dtype) for a, t in zip(state + params, inputs)]
            tape.zero()
        return (None, None, *adj)
