"""`Simulator`: one MLS-MPM substep per call, in the transfer variant the config names.

Per substep (Algorithm 1): particle regions → stress (plastic return, band release) → grid reset
→ P2G (shared or fragment-conditioned) → grid update (normalize + gravity per field, contact
projection, boundaries) → G2P (own field only). A frame is a whole number of substeps ending
exactly on the frame time; after it the divergence check (one host sync per frame) and the
fracture event provider run.
"""
from __future__ import annotations

import math
from typing import Optional

import torch
import warp as wp

from ..errors import SimulationDiverged
from ..config import MATERIALS, SimConfig
from ..variants import VARIANTS, variant_spec
from ..runtime import ensure_warp, torch_stream
from .boundary import Boundaries
from .constitutive import compute_stress, lame
from .grid import Grid, fit_grid
from .layout import EMPTY_BOX
from .particles import Particles, SimulationError
from .topology import Topology
from .transfer import clear_fields, g2p, grid_update, p2g

MULTIFIELD_VARIANTS = tuple(v for v, s in VARIANTS.items() if s.multifield)
RELEASE_VARIANTS = tuple(v for v, s in VARIANTS.items() if s.release)



def validate_sim_config(cfg: SimConfig) -> None:
    """One-sentence errors for invalid solver settings."""
    if cfg.variant not in VARIANTS:
        raise SimulationError(f"sim.variant '{cfg.variant}' is unknown; use one of {', '.join(VARIANTS)}")
    if cfg.material not in MATERIALS:
        raise SimulationError(f"sim.material '{cfg.material}' is unknown; use one of {', '.join(MATERIALS)}")
    for name in ("dt", "dx", "cfl"):
        value = getattr(cfg, name)
        if not (value > 0 and math.isfinite(value)):
            raise SimulationError(f"sim.{name} must be a positive number, not {value}")
    if cfg.eps_mass < 0 or cfg.eps_band < 0:
        raise SimulationError("sim.eps_mass and sim.eps_band must be >= 0")


def normalize_device(device) -> str:
    """'cpu', 'cuda' or 'cuda:N' → a device string both torch and Warp accept."""
    device = str(device)
    if device == "cuda":
        device = "cuda:0"
    if device.startswith("cuda"):
        if not torch.cuda.is_available():
            raise SimulationError(f"device '{device}' was requested but CUDA is not available here; use device='cpu'")
        return device
    if device != "cpu":
        raise SimulationError(f"device '{device}' is not 'cpu' or 'cuda:N'")
    return device


class Simulator:
    """MLS-MPM on torch tensors with Warp kernels; `particles` is shared with the kernels."""

    MUTABLE = ("x", "v", "C", "F", "yield_stress")  # what a substep writes into the particles

    def __init__(self, cfg: SimConfig, particles: Particles, device="cpu", provider=None):
        validate_sim_config(cfg)
        ensure_warp()
        self.cfg = cfg
        self.spec = variant_spec(cfg.variant)
        self.device = normalize_device(device)
        self.particles = particles.to(self.device)
        origin, dx, shape = fit_grid(cfg, self.particles.x)
        n_fields = 2 if self.spec.multifield else 1
        self.grid = Grid(origin, dx, shape, n_fields, self.device)
        self.boundaries = Boundaries(cfg.boundaries, self.device, shape, cfg.wall_cells)
        self.provider = provider
        self.topology: Optional[Topology] = None
        self.time = 0.0
        self.frame = 0
        self.substeps = 0
        self.dt = float(cfg.dt)
        n = len(self.particles)
        self.stress = torch.zeros(n, 3, 3, dtype=torch.float32, device=self.device)
        self.counts = torch.zeros(2, dtype=torch.int32, device=self.device)  # clamped to the walls, escaped a box
        self.box_slack = 0  # extra cells on every active box; grows when a frame had to be redone
        self.frame_redos = 0
        P = self.particles
        self.node_mass = float(P.mass.sum() / P.volume.sum()) * dx**3  # typical occupied-node mass ρ̄Δx³
        self.eps_m = cfg.eps_mass * self.node_mass
        self.eps_b = cfg.eps_band * self.node_mass
        mu, lam = lame(P.E.double(), P.nu.double())
        rho = (P.mass / P.volume).double()
        self.wave_speed = float(torch.sqrt((lam + 2 * mu) / rho).max())
        self._normal = wp.vec3(0.0, 0.0, 0.0)
        self._diagnostics = None
        self._saved = None  # frame-start state for a redo (`advance`)
        self.record_contact = True  # contact statistics for the diagnostics (off when timing)
        self._bind()

    # ---- set-up -------------------------------------------------------------------------------
    def _bind(self):
        """Warp views of the particle tensors, made once (zero-copy)."""
        P = self.particles
        self.wp = {k: wp.from_torch(getattr(P, k), dtype=wp.vec3) for k in ("x", "v")}
        self.wp.update({k: wp.from_torch(getattr(P, k), dtype=wp.mat33) for k in ("C", "F")})
        self.wp.update({k: wp.from_torch(getattr(P, k)) for k in ("mass", "volume", "E", "nu", "material", "yield_stress",
                                                                   "hardening", "alpha", "fragment", "band")})
        self.wp["stress"] = wp.from_torch(self.stress, dtype=wp.mat33)
        self.wp["clamped"] = wp.from_torch(self.counts[0:1])
        self.wp["escaped"] = wp.from_torch(self.counts[1:2])
        g = self.grid
        lo = [o + (self.cfg.wall_cells - 1) * g.dx for o in g.origin]
        hi = [o + (s - self.cfg.wall_cells) * g.dx for o, s in zip(g.origin, g.shape)]
        self._lower, self._upper = wp.vec3(*lo), wp.vec3(*hi)
        self._origin = wp.vec3(*g.origin)
        self._shape = wp.vec3i(*g.shape)
        self._gravity = wp.vec3(*[float(a) for a in self.cfg.gravity])
        self._reset_boxes()

    def _reset_boxes(self) -> None:
        """Grid work over the whole grid (until `fit_active_box`)."""
        g = self.grid
        full = (0, 0, 0) + tuple(g.shape)
        self.box = full  # active node box (lo, hi): where grid work happens
        g.set_boxes(full, full if self.multifield else EMPTY_BOX)
        self._box_origin = wp.vec3i(0, 0, 0)

    @property
    def field_boxes(self) -> tuple:
        """Node boxes (lo, hi) of field 0 (or the single field) and field 1 (the grid holds them)."""
        return self.grid.boxes

    def fit_active_box(self, horizon: float) -> float:
        """Restrict per-substep grid work to where particles can be during the next `horizon`
        seconds ("no work on empty grid"): per field, the bounding box of its particles plus the
        stencil, the distance they can travel (current speed and gravity) and `box_slack`. Slot 0
        covers their union, slot 1 only the boxes' intersection ("second fields only where
        fragments share support"). P2G counts any particle whose stencil has left its box, and
        `advance` redoes such a frame with more slack. One host read, which also returns max |v|
        for the CFL step; the grid is cleared whenever a box changes so no stale node survives."""
        P, g = self.particles, self.grid
        fields = [P.fragment <= 0, P.fragment == 1] if self.multifield else [torch.ones_like(P.fragment, dtype=torch.bool)]
        big = torch.tensor(3.0e38, device=P.x.device)
        rows = [torch.where(m[:, None], P.x, big).min(0).values for m in fields]
        rows += [torch.where(m[:, None], P.x, -big).max(0).values for m in fields]
        stats = torch.cat(rows + [P.v.norm(dim=1).max()[None]]).cpu()
        vmax = float(stats[-1])
        if not bool(torch.isfinite(stats).all()):
            return vmax  # the divergence check reports it
        travel = vmax * horizon + 0.5 * math.hypot(*self.cfg.gravity) * horizon**2
        pad = 3 + math.ceil(travel / g.dx) + self.box_slack
        n = len(fields)
        boxes = []
        for k in range(n):
            lo_w, hi_w = stats[3 * k:3 * k + 3], stats[3 * (n + k):3 * (n + k) + 3]
            if float(lo_w[0]) > float(hi_w[0]):  # empty field
                boxes.append(EMPTY_BOX)
                continue
            lo = [max(0, int(math.floor((float(lo_w[a]) - o) / g.dx)) - pad) for a, o in enumerate(g.origin)]
            hi = [min(s, int(math.floor((float(hi_w[a]) - o) / g.dx)) + 1 + pad) for a, (o, s) in enumerate(zip(g.origin, g.shape))]
            boxes.append(tuple(lo) + tuple(hi))
        live = [b for b in boxes if b[3] > b[0]]
        union = tuple(min(b[a] for b in live) for a in range(3)) + tuple(max(b[a] for b in live) for a in range(3, 6))
        boxes = tuple(boxes) if self.multifield else (union, EMPTY_BOX)
        if union != self.box or boxes != g.boxes:
            self.box = union
            g.set_boxes(*boxes)
            g.zero()
            self._box_origin = wp.vec3i(*union[:3])
        return vmax

    def _stream_scope(self):
        """Launch Warp on torch's current stream (DESIGN.md "Performance rules")."""
        return torch_stream(self.device)

    # ---- state queries -----------------------------------------------------------------------
    @property
    def latched(self) -> bool:
        return self.topology is not None

    @property
    def multifield(self) -> bool:
        """Fragment-conditioned transfer is in force (multi-field variant, after the latch)."""
        return self.latched and self.spec.multifield

    @property
    def release(self) -> bool:
        return self.latched and self.spec.release

    def cfl_dt(self, max_speed: float = 0.0) -> float:
        """Δt ≤ cfl·Δx / (max|v| + wave speed), wave speed √((λ+2μ)/ρ)."""
        return self.cfg.cfl * self.grid.dx / (max_speed + self.wave_speed)

    # ---- the substep ----------------------------------------------------------------------------
    def substep(self, dt: Optional[float] = None) -> None:
        """Advance by one substep Δt (default `cfg.dt`). Never syncs; allocates nothing, except slot 1
        of the grid on the first substep after boxes were reset without a refit (`latch` outside
        `advance`; `advance` refits, and so allocates, between frames)."""
        dt = float(self.dt if dt is None else dt)
        with self._stream_scope():
            self.boundaries.apply_regions(self.wp["x"], self.wp["v"], len(self.particles), self.time, dt, self.device)
            self.compute_stress(self.stress, commit=True)
            if self.latched and self.spec.per_fragment_pass:
                for k in (0, 1):
                    self._grid_pass(dt, only_fragment=k)
            else:
                self._grid_pass(dt, only_fragment=-1)
        self.time += dt
        self.substeps += 1

    def compute_stress(self, out: torch.Tensor, commit: bool) -> None:
        """Kirchhoff stress into `out` ([N,3,3]); `commit` writes the plastic return into F."""
        w = self.wp
        out_wp = w["stress"] if out is self.stress else wp.from_torch(out, dtype=wp.mat33)
        wp.launch(compute_stress, dim=len(self.particles), device=self.device,
                  inputs=[w["F"], w["material"], w["E"], w["nu"], w["yield_stress"], w["hardening"], w["alpha"], w["band"],
                          int(self.release), int(commit), out_wp])

    def _grid_pass(self, dt: float, only_fragment: int) -> None:
        """Grid reset, P2G, grid update, G2P over all particles or one fragment's."""
        self.p2g(dt, only_fragment)
        self.update_grid(dt)
        self.g2p(dt, only_fragment)

    def p2g(self, dt: float, only_fragment: int = -1, target=None, multifield=None, stress=None) -> None:
        """Reset the active fields and scatter particles into them (Eq. multifield_p2g).

        `target` (a Grid), `multifield` and `stress` (a Warp view) override the destination, the
        routing and the stress; the diagnostics use them for the per-fragment shadow transfer."""
        g, w = target or self.grid, self.wp
        multi = int(self.multifield if multifield is None else multifield)
        g.ensure()
        if target is None:
            b = self.box
            wp.launch(clear_fields, dim=(b[3] - b[0], b[4] - b[1], b[5] - b[2]), device=self.device,
                      inputs=[self._box_origin, self._shape, *g.wp_support, g.wp["mp"], g.wp["mb"]])
        else:
            g.clear()
        wp.launch(p2g, dim=len(self.particles), device=self.device,
                  inputs=[w["x"], w["v"], w["C"], w["mass"], w["volume"], w["stress"] if stress is None else stress,
                          w["fragment"], w["band"], multi, only_fragment, dt, self._origin, g.dx, 1.0 / g.dx, self._shape,
                          *g.wp_support, *g.wp_boxes, g.wp["mp"], g.wp["mb"], w["escaped"]])

    def update_grid(self, dt: float) -> None:
        """Normalize + gravity per active field, contact projection (full), boundaries."""
        g, multi = self.grid, int(self.multifield)
        g.ensure()
        self.boundaries.colliders.wall_cells = int(self.cfg.wall_cells)  # the config may change between calls
        b = self.box
        wp.launch(grid_update, dim=(b[3] - b[0], b[4] - b[1], b[5] - b[2]), device=self.device,
                  inputs=[self._box_origin, self._shape, *g.wp_support, g.wp["mp"], g.wp["mb"], g.wp["vel"], self.eps_m,
                          self.eps_b, multi, int(multi and self.spec.contact), self._normal, float(self.cfg.restitution), dt, self._gravity, self._origin, g.dx, self.time,
                          self.boundaries.colliders, int(self.record_contact), g.wp["stats"]])

    def g2p(self, dt: float, only_fragment: int = -1) -> None:
        """Gather v, C, F's update and x from each particle's own field (Eq. field_g2p)."""
        g, w = self.grid, self.wp
        g.ensure()
        wp.launch(g2p, dim=len(self.particles), device=self.device,
                  inputs=[w["x"], w["v"], w["C"], w["F"], w["fragment"], int(self.multifield), only_fragment, dt,
                          self._origin, g.dx, 1.0 / g.dx, self._shape, *g.wp_support, g.wp["vel"],
                          self._lower, self._upper, w["clamped"]])

    # ---- frames -------------------------------------------------------------------------------
    def frame_substeps(self, frame_dt: float, vmax: Optional[float] = None) -> tuple[int, float]:
        """(n, Δt) with n·Δt = frame_dt exactly and Δt ≤ cfg.dt (and the CFL bound if adaptive;
        `vmax`, the largest particle speed, is read from the device when not given)."""
        dt = self.cfg.dt
        if self.cfg.adaptive_dt:
            if vmax is None:
                vmax = float(self.particles.v.norm(dim=1).max())
            if math.isfinite(vmax):
                dt = min(dt, self.cfl_dt(vmax))
        n = max(1, math.ceil(frame_dt / dt - 1e-9))
        if n > self.cfg.max_substeps_per_frame:
            raise SimulationError(f"a frame of {frame_dt}s needs {n} substeps of {dt:.3g}s, over sim.max_substeps_per_frame")
        return n, frame_dt / n

    def advance(self, frame_dt: float) -> int:
        """Simulate one frame: n substeps, then the divergence check and the event provider.

        The frame runs on active boxes fitted at its start. If a particle's stencil left its box
        (P2G counts it; read with the divergence check), the frame is rolled back and redone with
        more box slack; a third try runs on the whole grid, where nothing can escape."""
        if self.substeps == 0:
            self._poll_provider()  # an oracle may latch before the first substep
        start, substeps0 = self.time, self.substeps
        self._save_state()
        for attempt in range(3):
            if attempt < 2:
                vmax = self.fit_active_box(frame_dt)  # the frame's one host read also gives max |v|
            else:
                self._reset_boxes()
                vmax = None
            n, dt = self.frame_substeps(frame_dt, vmax)
            self.dt = dt
            self.counts[1] = 0
            for _ in range(n):
                self.substep(dt)
            bad, escaped = self._frame_check(dt)
            if escaped == 0 or attempt == 2:
                break
            self._restore_state()
            self.time, self.substeps = start, substeps0
            self.box_slack = 2 * self.box_slack + 2
            self.frame_redos += 1
        self.time = start + frame_dt  # end exactly on the frame time (no drift from summing Δt)
        self.frame += 1
        if bad:
            self._raise_diverged(dt, bad)
        self._poll_provider()
        if self._diagnostics is not None:
            self._diagnostics.on_frame()
        return n

    def _save_state(self) -> None:
        """Copy what a frame can change into buffers made once (device copies, no sync)."""
        P = self.particles
        if self._saved is None:
            self._saved = {k: torch.empty_like(getattr(P, k)) for k in self.MUTABLE}
            self._saved["stats"] = torch.empty_like(self.grid.contact_stats)
            self._saved["counts"] = torch.empty_like(self.counts)
        for k in self.MUTABLE:
            self._saved[k].copy_(getattr(P, k))
        self._saved["stats"].copy_(self.grid.contact_stats)
        self._saved["counts"].copy_(self.counts)

    def _restore_state(self) -> None:
        P = self.particles
        for k in self.MUTABLE:
            getattr(P, k).copy_(self._saved[k])
        self.grid.contact_stats.copy_(self._saved["stats"])
        self.counts.copy_(self._saved["counts"])

    def _poll_provider(self) -> None:
        """Ask the event provider for a topology; the first one returned is latched, once."""
        if self.provider is not None and not self.latched:
            topology = self.provider(self)
            if topology is not None:
                self.latch(topology)

    def _bad_particles(self, dt: float) -> torch.Tensor:
        """Particles that are non-finite or faster than Δx/Δt (a device count)."""
        P = self.particles
        speed = P.v.norm(dim=1)
        bad = ~torch.isfinite(speed) | ~torch.isfinite(P.x).all(dim=1) | (speed > self.grid.dx / dt)
        return bad.sum()

    def _frame_check(self, dt: float) -> tuple[int, int]:
        """(diverged particles, box escapes) of the frame, in one host read."""
        bad, escaped = torch.stack([self._bad_particles(dt), self.counts[1].long()]).tolist()
        return int(bad), int(escaped)

    def _raise_diverged(self, dt: float, count: int) -> None:
        bound = self.cfl_dt()
        cause = (f"Δt = {dt:.3g}s is over the CFL bound {bound:.3g}s for this stiffness (wave speed {self.wave_speed:.3g} m/s)"
                 if dt > bound else "an extreme deformation or boundary velocity")
        raise SimulationDiverged(
            f"simulation diverged at frame {self.frame} (t = {self.time:.4g}s): {count} of {len(self.particles)} particles have a "
            f"non-finite or exploding velocity; likely cause: {cause}. Lower sim.dt or set sim.adaptive_dt = true.",
            frame=self.frame, count=count, cause=cause)

    # ---- topology -----------------------------------------------------------------------------
    def latch(self, topology: Topology) -> None:
        """Impulse-free latch (Eq. state_inheritance): only o_p, γ_p and n_Π are written."""
        if self.latched:
            raise SimulationError("this simulation has already latched a topology; a binary run latches once")
        P = self.particles
        if topology.fragment.shape != (len(P),) or topology.band.shape != (len(P),):
            raise SimulationError(f"Topology labels must have shape [{len(P)}] like the particles")
        P.fragment.copy_(topology.fragment.to(P.fragment.device, torch.int32))
        P.band.copy_(topology.band.to(P.band.device, torch.int32))
        n = torch.tensor(topology.normal, dtype=torch.float64)
        self._normal = wp.vec3(*[float(a) for a in n / n.norm()])
        self.topology = topology
        self._reset_boxes()  # the routing changed: the next advance() refits one box per field
        if self._diagnostics is not None:
            self._diagnostics.on_latch()

    def clamped_count(self) -> int:
        """Particles clamped to the domain walls so far (host read)."""
        return int(self.counts[0].item())

    def diagnostics(self) -> dict:
        """Metrics of DESIGN.md "Diagnostics" for the current state (see `diagnostics.py`)."""
        return self.diagnostics_tracker().snapshot()

    def diagnostics_tracker(self):
        if self._diagnostics is None:
            from .diagnostics import Diagnostics

            self._diagnostics = Diagnostics(self)
        return self._diagnostics

    def sort_particles(self, mode: str = "interleaved") -> torch.Tensor:
        """Reorder particles for P2G's atomics; returns `order` (new particle i was old order[i]).

        `cell`: grid-cell order (locality, but the ~8 particles of a cell sit in one warp and hit the
        same 27 nodes). `interleaved`: the k-th particle of every cell, in cell order, then the
        (k+1)-th, ... — neighbours in memory are neighbouring cells, so a warp keeps locality while
        few of its lanes add to the same node."""
        P, g = self.particles, self.grid
        cell = torch.floor((P.x - torch.tensor(g.origin, device=P.x.device)) / g.dx).long()
        key = (cell[:, 0] * g.shape[1] + cell[:, 1]) * g.shape[2] + cell[:, 2]
        order = torch.argsort(key, stable=True)
        if mode == "interleaved":
            sorted_key = key[order]
            _, counts = torch.unique_consecutive(sorted_key, return_counts=True)
            starts = torch.repeat_interleave(torch.cumsum(counts, 0) - counts, counts)
            rank = torch.arange(len(order), device=key.device) - starts
            order = order[torch.argsort(rank * (int(sorted_key.max()) + 1) + sorted_key, stable=True)]
        elif mode != "cell":
            raise ValueError(f"sort mode '{mode}' is not 'cell' or 'interleaved'")
        P.permute(order)
        return order
