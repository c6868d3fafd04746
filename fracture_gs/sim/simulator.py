"""`Simulator`: one MLS-MPM substep per call, in the transfer variant the config names.

Per substep (Algorithm 1): particle regions → stress (plastic return, band release) → grid reset
→ P2G (shared or fragment-conditioned, any number of fragments) → grid update (normalize + gravity
per field; at multi-fragment nodes the contact projection between every pair of fields; then
boundaries) → G2P (own field only). Frames of substeps (checks, redo, CUDA graph replay, the
event provider) are `frame_loop.FrameLoop`, mixed in.
"""

from __future__ import annotations

import contextlib
import math
from typing import Optional, get_args

import torch
import warp as wp

from ..config import MATERIALS, ParticleOrder, SimConfig
from ..runtime import StreamFork, cpu_ranges, ensure_warp, launch, run_ranges, torch_stream
from ..variants import VARIANT_NAMES, variant_spec
from .boxes.fragment_boxes import FragmentBoxes
from .clock import FrameClock
from .frame_loop import FrameLoop
from .grid.domain import check_inside, fit_grid
from .grid.fanout_kernels import LANES, g2p_fanout, p2g_fanout
from .grid.fields import Grid
from .grid.kernels import clear_dense, clear_pool, g2p, grid_update_dense, p2g
from .grid.run_kernels import p2g_runs
from .grid.slots import SlotStorage
from .neighbourhood import cell_order, fragment_centroids
from .particles import Particles, SimulationError
from .physics.boundary import Boundaries
from .physics.constitutive import compute_stress, lame
from .physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from .recorded import Recorded
from .storage import COUNT_CLAMPED, MAX_SLOTS, N_COUNTS
from .topology import Topology

P2G_RUN = 8  # particles per P2G thread in cell order on a GPU: runs of 8 were the fastest on the Table 2 ficus (P2G
# under half its time one per thread); not while most particles take the slot path (slower there; BENCHMARKS.md)


def validate_sim_config(cfg: SimConfig) -> None:
    """One-sentence errors for invalid solver settings."""
    if cfg.variant not in VARIANT_NAMES:
        raise SimulationError(f"sim.variant '{cfg.variant}' is unknown; use one of {', '.join(VARIANT_NAMES)}")
    if cfg.material not in MATERIALS:
        raise SimulationError(f"sim.material '{cfg.material}' is unknown; use one of {', '.join(MATERIALS)}")
    for name in ("dt", "dx", "cfl"):
        value = getattr(cfg, name)
        if not (value > 0 and math.isfinite(value)):
            raise SimulationError(f"sim.{name} must be a positive number, not {value}")
    if cfg.eps_mass < 0 or cfg.eps_band < 0:
        raise SimulationError("sim.eps_mass and sim.eps_band must be >= 0")
    if not 2 <= cfg.field_slots <= MAX_SLOTS:
        raise SimulationError(f"sim.field_slots = {cfg.field_slots} must lie in [2, {MAX_SLOTS}]")
    if cfg.grid_storage not in ("auto", "slots", "boxes"):
        raise SimulationError(f"sim.grid_storage '{cfg.grid_storage}' is unknown; use auto, slots or boxes")
    if cfg.particle_order not in get_args(ParticleOrder):
        orders = " or ".join(get_args(ParticleOrder))
        raise SimulationError(f"sim.particle_order '{cfg.particle_order}' is unknown; use {orders}")
    if not 2 <= cfg.max_fragments <= 4096:
        raise SimulationError(f"sim.max_fragments = {cfg.max_fragments} must lie in [2, 4096]")
    if not (cfg.contact.friction >= 0 and math.isfinite(cfg.contact.friction)):
        raise SimulationError(f"sim.contact.friction = {cfg.contact.friction} must be a finite number >= 0")


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


class Simulator(SlotStorage, FrameLoop):
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
        check_inside(self.particles.x, origin, dx, shape)
        storage = cfg.grid_storage if self.spec.multifield else "none"  # one field: neither slots nor boxes
        slots = cfg.field_slots if storage == "slots" else 1  # boxes (auto) keep no slots, owner words or pool
        self.grid = Grid(origin, dx, shape, self.device, slots, cfg.max_fragments)
        # the fragment fields after a latch in dense boxes, one per fragment (`boxes/`), instead of slots
        boxed = storage in ("auto", "boxes")
        self.boxes = FragmentBoxes(shape, origin, dx, self.device, cfg.max_fragments) if boxed else None
        self.boundaries = Boundaries(cfg.boundaries, self.device, shape, cfg.wall_cells)
        self.clock = FrameClock(self.device, len(self.boundaries.regions))
        self.use_graphs = True  # CUDA: replay one recorded substep per substep of a frame
        self._graph = None
        self._graph_key_value = None
        self._cuda_stream = None
        self.provider = provider
        self.topology: Optional[Topology] = None
        self.topologies: list[Topology] = []  # every latched topology, in order (repeated fracture)
        self.n_fragments = 1
        self.time = 0.0
        self.frame = 0
        self.substeps = 0
        self.dt = float(cfg.dt)
        n = len(self.particles)
        self.stress = torch.zeros(n, 3, 3, dtype=torch.float32, device=self.device)
        self.solo = torch.zeros(n, dtype=torch.int32, device=self.device)  # see `_update_solo`
        self.concurrent = True  # CUDA: P2G's and the grid update's independent launches on two streams (`_beside`)
        self._fork = StreamFork(self.device)
        self.one_gather = True  # G2P fan-out: the solo particles in the fan-out's launch (`g2p_fanout`)
        self._queries = Recorded(self.device)  # CUDA: the per-frame solo mask as recorded graphs
        self._zeros = torch.zeros(n, dtype=torch.int32, device=self.device)  # a per-particle flag that reads 0
        # The particles that are not solo (1.6 % at K = 2 on the Table 2 ficus) do 27 serial slot lookups
        # each; on a GPU their threads finished long after the dense bulk. `fanout` (CUDA default) gives
        # each of them one thread per stencil node in P2G, and a warp in G2P while they are at most
        # `g2p_fanout_max` of the particles (`grid/fanout_kernels.py`; when they are the bulk, per-particle threads
        # already fill the GPU and the warp's shuffles only cost: BENCHMARKS.md). The launches cover a
        # power-of-two capacity ≥ their count, read once per frame in `set_solo` (graphs record again only
        # when it changes). `slow_first`, the earlier remedy, launches them first in G2P otherwise.
        self.slow_first = self.device.startswith("cuda")
        self.fanout = self.device.startswith("cuda")
        self.g2p_fanout_max = 1.0 / 16
        # P2G of the dense-path particles in runs of `p2g_run` consecutive particles, summed in registers while
        # they share a cell (`grid/run_kernels.py`): on (runs of P2G_RUN) for particles sorted by cell on a GPU
        # (`sort_particles("cell")`, or `sim.particle_order = "cell"`: the caller sorted them), where it saves
        # global reductions; 0: one thread per particle (runs are correct in any order, only slower out of it)
        self.p2g_run = P2G_RUN if cfg.particle_order == "cell" and self.device != "cpu" else 0
        self._slow = n
        self._fan_cap = 0
        # buffer index of every (listed particle, stencil node) that P2G's fan-out deposited into, read back
        # by G2P in the same substep instead of looking the slot up again
        self._slot_cache = torch.zeros(1, dtype=torch.int32, device=self.device)
        self._grad0 = None  # see `_pool_gradient_buffer`
        self._order = torch.arange(n, dtype=torch.int32, device=self.device)
        self._first = torch.full((1,), n, dtype=torch.int32, device=self.device)
        self.counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=self.device)  # see storage.COUNT_*
        self.box_slack = 0  # extra cells on the active box; grows when a frame had to be redone
        self.frame_redos = 0
        self.pool_rows = 0  # multi-fragment nodes expected per substep (sizes the grid's pool)
        self.slot_overflow = 0  # deposits that found no free slot, in the last frame
        self.slot_overflow_total = 0
        self.pool_overflow = 0  # pool insertions that failed in the last accepted frame
        P = self.particles
        self.node_mass = float(P.mass.sum() / P.volume.sum()) * dx**3  # typical occupied-node mass ρ̄Δx³
        self.eps_m = cfg.eps_mass * self.node_mass
        self.eps_b = cfg.eps_band * self.node_mass
        mu, lam = lame(P.E.double(), P.nu.double())
        rho = (P.mass / P.volume).double()
        self.wave_speed = float(torch.sqrt((lam + 2 * mu) / rho).max())
        self._normal = wp.vec3(0.0, 0.0, 0.0)
        self.normal_mode = NORMAL_LATCHED
        self.centroids = torch.zeros(cfg.max_fragments, 3, dtype=torch.float32, device=self.device)
        self._diagnostics = None
        self._saved = None  # frame-start state for a redo (`advance`)
        self.record_contact = True  # contact statistics for the diagnostics (off when timing)
        self._ranges = cpu_ranges(n) if self.device == "cpu" else None  # per-particle kernels over the CPU's cores
        self._range_counts = None  # G2P's clamp counter per range (CPU)
        self._bind()

    # ---- set-up -------------------------------------------------------------------------------
    def _bind(self):
        """Warp views of the particle tensors, made once (zero-copy)."""
        P = self.particles
        self.wp = {k: wp.from_torch(getattr(P, k), dtype=wp.vec3) for k in ("x", "v")}
        self.wp.update({k: wp.from_torch(getattr(P, k), dtype=wp.mat33) for k in ("C", "F")})
        self.wp.update(
            {
                k: wp.from_torch(getattr(P, k))
                for k in (
                    "mass",
                    "volume",
                    "E",
                    "nu",
                    "material",
                    "yield_stress",
                    "hardening",
                    "alpha",
                    "fragment",
                    "band",
                )
            }
        )
        self.wp["stress"] = wp.from_torch(self.stress, dtype=wp.mat33)
        self.wp["counts"] = wp.from_torch(self.counts)
        self.wp["solo"] = wp.from_torch(self.solo)
        self.wp["zeros"] = wp.from_torch(self._zeros)
        self.wp["order"] = wp.from_torch(self._order)
        self.wp["first"] = wp.from_torch(self._first)
        self.wp["slot_cache"] = wp.from_torch(self._slot_cache)
        self.wp["centroids"] = wp.from_torch(self.centroids, dtype=wp.vec3)
        g = self.grid
        lo = [o + (self.cfg.wall_cells - 1) * g.dx for o in g.origin]
        hi = [o + (s - self.cfg.wall_cells) * g.dx for o, s in zip(g.origin, g.shape)]
        self._lower, self._upper = wp.vec3(*lo), wp.vec3(*hi)
        self._gravity = wp.vec3(*[float(a) for a in self.cfg.gravity])
        self._reset_boxes()

    def _reset_boxes(self) -> None:
        """Grid work over the whole grid (until `fit_active_box`)."""
        self._set_box((0, 0, 0) + tuple(self.grid.shape))

    def _set_box(self, box: tuple) -> None:
        self.box = tuple(box)  # active node box (lo, hi): where grid work happens
        self.grid.box = self.box
        self._box_lo, self._box_hi = wp.vec3i(*box[:3]), wp.vec3i(*box[3:])

    def fit_active_box(self, horizon: float) -> float:
        """Restrict per-substep grid work to where particles can be during the next `horizon`
        seconds ("no work on empty grid"): the particles' bounding box plus the stencil, the
        distance they can travel (current speed and gravity) and `box_slack`. P2G counts any
        particle whose stencil has left the box, and `advance` redoes such a frame with more slack.
        One host read, which also returns max |v| for the CFL step; the grid is cleared whenever
        the box changes so no stale node survives. The pool is sized here, between frames."""
        P, g = self.particles, self.grid
        stats = torch.cat([P.x.min(0).values, P.x.max(0).values, P.v.norm(dim=1).max()[None]]).cpu()
        vmax = float(stats[-1])
        if not bool(torch.isfinite(stats).all()):
            return vmax  # the divergence check reports it
        travel = vmax * horizon + 0.5 * math.hypot(*self.cfg.gravity) * horizon**2
        pad = 3 + math.ceil(travel / g.dx) + self.box_slack
        lo = [max(0, int(math.floor((float(stats[a]) - o) / g.dx)) - pad) for a, o in enumerate(g.origin)]
        hi = [
            min(s, int(math.floor((float(stats[3 + a]) - o) / g.dx)) + 1 + pad)
            for a, (o, s) in enumerate(zip(g.origin, g.shape))
        ]
        box = tuple(lo) + tuple(hi)
        if self.multifield and self.normal_mode == NORMAL_MASS_GRADIENT:
            self._update_centroids()
        if self.boxed:  # each fragment's box: its stencils plus the travel and the slack (`fit` reads the node
            # total and the overlap lists' length); the dense grid's active box stays put (no box launch reads it,
            # and it is in the graph key)
            self.boxes.fit(P.x, P.fragment, 1 + math.ceil(travel / g.dx) + self.box_slack, self.n_fragments)
            return vmax
        moved = g.ensure_pool(self.pool_rows) if self.multifield else False
        if self.multifield:
            self._pool_gradient_buffer()
        if box != self.box or moved:
            self._set_box(box)
            g.zero()
        if self.multifield:
            self._update_solo(travel)
        return vmax

    def _update_centroids(self) -> None:
        """Mass centroid of every fragment (the contact normal's fallback), on the device."""
        P = self.particles
        self.centroids.copy_(fragment_centroids(P.x, P.mass, P.fragment, self.cfg.max_fragments))

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
    def boxed(self) -> bool:
        """The fragment fields are in per-fragment boxes (after the latch, unless `sim.grid_storage = "slots"`)."""
        return self.boxes is not None and self.multifield

    def box_fields(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """With the boxes: a substep's fields at the current particles, as the slot storage's grid views give
        them after a substep (mass [K, X, Y, Z], momentum and velocity [K, X, Y, Z, 3], band mass [K, X, Y, Z]).
        The boxes are emptied right after each substep, so this deposits the particles again and runs the grid
        update (no G2P, no contact statistics, escapes counted apart), reads the fields and empties the boxes."""
        if not self.boxed:
            raise SimulationError("box_fields needs the fields in per-fragment boxes (after a latch, boxed storage)")
        record, self.record_contact = self.record_contact, False
        try:
            with self._stream_scope():
                scratch = torch.zeros_like(self.counts)  # escapes here are not the frame's
                self._p2g(counts=wp.from_torch(scratch))
                self._update_boxes()
                fields = self.boxes.dense(self.n_fragments)
                self.boxes.clear()
        finally:
            self.record_contact = record
        return fields

    @property
    def grid_nbytes(self) -> int:
        """Bytes of the grid buffers this simulator holds: the grid (dense, with slots and pool) and, when the
        storage may use them, the per-fragment boxes."""
        return self.grid.nbytes + (self.boxes.nbytes if self.boxes is not None else 0)

    @property
    def release(self) -> bool:
        return self.latched and self.spec.release

    def cfl_dt(self, max_speed: float = 0.0) -> float:
        """Δt ≤ cfl·Δx / (max|v| + wave speed), wave speed √((λ+2μ)/ρ)."""
        return self.cfg.cfl * self.grid.dx / (max_speed + self.wave_speed)

    # ---- the substep ----------------------------------------------------------------------------
    def substep(self, dt: Optional[float] = None) -> None:
        """Advance by one substep Δt (default `cfg.dt`). Never syncs and allocates nothing."""
        dt = float(self.dt if dt is None else dt)
        on = self._set_clock(dt, [self.time])
        with self._stream_scope():
            self._substep_launches(on)
        self.time += dt
        self.substeps += 1

    def set_clock(self, dt: float) -> None:
        """Set the substep Δt the kernels read (for `transfer` and recorded graphs of it, e.g. benchmarks)."""
        self._set_clock(float(dt), [self.time])

    def transfer(self) -> None:
        """One substep's transfer with the clock's Δt: grid reset, P2G, grid update, G2P (once per
        fragment for the global fragment pass). Launches only: safe inside a graph capture."""
        if self.latched and self.spec.per_fragment_pass:
            for k in range(self.n_fragments):
                self._grid_pass(only_fragment=k)
        else:
            self._grid_pass(only_fragment=-1)

    def compute_stress(self, out: torch.Tensor, commit: bool) -> None:
        """Kirchhoff stress into `out` ([N,3,3]); `commit` writes the plastic return into F. A per-particle
        kernel: on the CPU it runs as one launch per core's share of the particles (bitwise the same)."""
        w = self.wp
        out_wp = w["stress"] if out is self.stress else wp.from_torch(out, dtype=wp.mat33)
        arrays = [w["F"], w["material"], w["E"], w["nu"], w["yield_stress"], w["hardening"], w["alpha"], w["band"]]
        release = self.topology.release_events if self.release else 0

        def launch(a: int, b: int) -> None:
            self._launch(compute_stress, b - a, [t[a:b] for t in arrays] + [release, int(commit), out_wp[a:b]])

        n = len(self.particles)
        if self.device == "cpu":
            run_ranges(launch, self._ranges if self._ranges is not None else [(0, n)])
        else:
            launch(0, n)

    def _grid_pass(self, only_fragment: int) -> None:
        """Grid reset, P2G, grid update, G2P over all particles or one fragment's (Δt from the clock)."""
        self._p2g(only_fragment)
        self._update_grid()
        self._g2p(only_fragment)

    def p2g(self, dt: float, only_fragment: int = -1, target=None, multifield=None, stress=None, counts=None) -> None:
        """Reset the active fields and scatter particles into them (Eq. multifield_p2g), with substep Δt.

        `target` (a Grid), `multifield`, `stress` (a Warp view) and `counts` (a Warp int32 array)
        override the destination, the routing, the stress and the counters; the diagnostics use
        them for the per-fragment shadow transfer."""
        self._set_clock(float(dt), [self.time])
        self._p2g(only_fragment, target, multifield, stress, counts)

    def update_grid(self, dt: float) -> None:
        """Normalize + gravity per active field, contact projection (full), boundaries, with substep Δt."""
        self._set_clock(float(dt), [self.time])
        self._update_grid()

    def g2p(self, dt: float, only_fragment: int = -1) -> None:
        """Gather v, C, F's update and x from each particle's own field (Eq. field_g2p), with substep Δt."""
        self._set_clock(float(dt), [self.time])
        self._g2p(only_fragment)

    def _p2g(self, only_fragment: int = -1, target=None, multifield=None, stress=None, counts=None) -> None:
        g, w = target or self.grid, self.wp
        if self.boxed and target is None and multifield is None and stress is None:
            band = w["band"] if self.normal_mode == NORMAL_LATCHED else None  # the latched gate's band masses
            self.boxes.p2g(w, self.clock.view, w["counts"] if counts is None else counts, self.p2g_run, band_flags=band)
            return
        multi = int(self.multifield if multifield is None else multifield)
        fan = target is None and self._fans_out(multi, only_fragment)
        side = self._beside(on=fan)  # the pool's reset and the fan-out beside the dense deposits
        if target is None:
            b = self.box
            self._launch(clear_dense, (b[3] - b[0], b[4] - b[1], b[5] - b[2]), [g.view, self._box_lo])
            if multi:
                with side:
                    self._launch(clear_pool, g.capacity, [g.view])
            lo, hi = self._box_lo, self._box_hi
        else:
            g.clear()
            lo, hi = wp.vec3i(0, 0, 0), wp.vec3i(*g.shape)
        run = self._run_length(multi) if target is None and only_fragment < 0 and (fan or not multi) else 0
        counts = w["counts"] if counts is None else counts
        particle_arrays = [w[k] for k in ("x", "v", "C", "mass", "volume")]  # what P2G reads of each particle
        # band particles give every node they reach a pool row holding their band mass, which only the contact
        # gate of latched normals reads: with mass-gradient normals (K > 2) their flags read 0 in P2G
        band = w["band"] if target is not None or self.normal_mode == NORMAL_LATCHED else w["zeros"]
        particle_arrays += [w["stress"] if stress is None else stress, w["fragment"], band]
        if run > 0:  # `grid.run_kernels.p2g_runs` takes only the first six: its particles are on the dense path
            extra = [w["solo"], multi, run, self.clock.view, g.view, lo, hi, counts]
            dim = -(-len(self.particles) // run)
            self._launch(p2g_runs, dim, particle_arrays[:6] + extra)
        else:
            extra = [w["solo"] if target is None else w["zeros"], multi, only_fragment, int(fan), self.clock.view]
            extra += [g.view, lo, hi, counts]
            self._launch(p2g, len(self.particles), particle_arrays + extra)
        if fan:
            extra = [w["order"], w["first"], w["slot_cache"], self.clock.view, g.view, counts]
            with side:
                self._launch(p2g_fanout, 27 * self._fan_cap, particle_arrays + extra)
            self._fork.join()

    def _update_grid(self) -> None:
        g, multi = self.grid, int(self.multifield)
        self.boundaries.colliders.wall_cells = int(self.cfg.wall_cells)  # the config may change between calls
        if self.boxed:
            self._update_boxes()
            return
        if multi:  # the nodes with a pool row, beside the dense pass (they write disjoint nodes)
            with self._beside():
                self._update_pool()
        b = self.box
        dense = [g.view, self._box_lo, multi, self.eps_m, self.clock.view, self._gravity, self.boundaries.colliders]
        self._launch(grid_update_dense, (b[3] - b[0], b[4] - b[1], b[5] - b[2]), dense)
        self._fork.join()

    def _update_boxes(self) -> None:
        """Every fragment box's normalization, contact where fields meet, boundaries (`box_grid_update`)."""
        g, c = self.grid, self.cfg.contact
        stats = (g.wp["stats"], g.wp["pair_stats"], g.pair_fragments) if self.record_contact else None
        self.boxes.update(
            self.clock.view, self.eps_m, self._gravity, c.fill * self.node_mass, self.wp["centroids"],
            self.wp["counts"], self.boundaries.colliders, e=float(self.cfg.restitution), mu=float(c.friction),
            latched=self._normal, eps_b=self.eps_b, project=bool(self.spec.contact),
            stats=stats, mass_gradient=self.normal_mode == NORMAL_MASS_GRADIENT, slots=self.cfg.field_slots,
        )  # fmt: skip

    def _g2p(self, only_fragment: int = -1) -> None:
        """Per particle but for the clamp counter: on the CPU one launch per core's share, each with its
        own counter."""
        g, w = self.grid, self.wp
        if self.boxed and only_fragment < 0:
            lo, hi = self._lower, self._upper
            if self.concurrent:
                self._fork.open()  # the next P2G's empty boxes go beside this G2P (which reads only velocities),
            self._g2p_ranges(lambda a, b, c: self.boxes.g2p(w, self.clock.view, lo, hi, c, a, b), False)
            with self._beside():  # issued after it, so G2P's blocks take the SMs first and the clear fills its tail
                self.boxes.clear()
            self._fork.join()
            return
        arrays = [w["x"], w["v"], w["C"], w["F"], w["fragment"], w["solo"]]
        multi = int(self.multifield)
        fan = self._fans_out(multi, only_fragment, gather=True)
        split = self._split(multi) and not fan
        cached = int(self._fans_out(multi, only_fragment))  # this substep's P2G filled the slot cache

        def launch(a: int, b: int, counts) -> None:
            self._launch(
                g2p,
                (b - a) * (2 if split else 1),
                [t[a:b] for t in arrays]
                + [w["order"], w["first"], int(split), int(fan), w["slot_cache"], cached]
                + [multi, only_fragment, self.clock.view, g.view, self._lower, self._upper, counts],
            )

        if fan:  # with `one_gather` the solo particles too, in the same launch behind the listed ones
            listed = LANES * self._fan_cap if self.one_gather else 0
            self._launch(
                g2p_fanout,
                LANES * self._fan_cap + (len(self.particles) if listed else 0),
                arrays[:5]
                + [w["order"], w["first"], w["slot_cache"], cached, int(self.device.startswith("cuda"))]
                + [self.clock.view, g.view]
                + [self._lower, self._upper, w["counts"], w["solo"], listed],
            )
            if listed:
                return
        self._g2p_ranges(launch, split)

    def _g2p_ranges(self, launch, whole: bool) -> None:
        """G2P's `launch(a, b, counts)` over the particles: on the CPU once per core's share (unless `whole`),
        each share with its own clamp counter, summed after."""
        w = self.wp
        ranges = [(0, len(self.particles))] if whole or not self._ranges else self._ranges
        if len(ranges) == 1:
            launch(*ranges[0], w["counts"])
            return
        if self._range_counts is None:
            self._range_counts = torch.zeros(len(ranges), N_COUNTS, dtype=torch.int32, device=self.device)
            self._range_counts_wp = [wp.from_torch(c) for c in self._range_counts]
        self._range_counts.zero_()
        run_ranges(lambda a, b: launch(a, b, self._range_counts_wp[ranges.index((a, b))]), ranges)
        self.counts += self._range_counts.sum(0, dtype=torch.int32)

    def _launch(self, kernel, dim, inputs: list) -> None:
        launch(kernel, dim, inputs, self.device)

    def _beside(self, on: bool = True):
        """Context for launches that need nothing issued after the last join and that nothing reads before
        the next one: on a GPU with `concurrent` (and `on`) they go to the fork's stream (`runtime.StreamFork`)."""
        return self._fork if on and self.concurrent else contextlib.nullcontext()

    # ---- frames -------------------------------------------------------------------------------
    # ---- topology -----------------------------------------------------------------------------
    def latch(self, topology: Topology) -> None:
        """Impulse-free latch (Eq. state_inheritance): only o_p, γ_p (and the contact normal) are
        written. May be called again with a refined topology (repeated fracture): every latch is
        impulse-free, and the fragment ids only grow."""
        P = self.particles
        if topology.fragment.shape != (len(P),) or topology.band.shape != (len(P),):
            raise SimulationError(f"Topology labels must have shape [{len(P)}] like the particles")
        fragment = topology.fragment.to(P.fragment.device, torch.int32)
        k, bands = (
            int(v) for v in torch.stack([fragment.max().long(), topology.band.to(fragment.device).bool().sum()])
        )
        if not (0 <= int(fragment.min()) and k < self.cfg.max_fragments):
            raise SimulationError(
                f"Topology fragment ids must lie in [0, sim.max_fragments = {self.cfg.max_fragments}); got up to {k}"
            )
        first = self.topology is None
        P.fragment.copy_(fragment)
        P.band.copy_(topology.band.to(P.band.device, torch.int32))
        if first:
            n = torch.tensor(topology.normal, dtype=torch.float64)
            self._normal = wp.vec3(*[float(a) for a in n / n.norm()])
        self.topology = topology
        self.topologies.append(topology)
        self.n_fragments = max(self.n_fragments, k + 1)
        self.grid.n_fields = self.n_fragments if self.spec.multifield else 1
        mode = self.cfg.contact.normal
        binary = len(getattr(topology, "events", ())) <= 1 and self.n_fragments <= 2
        self.normal_mode = NORMAL_LATCHED if mode == "latched" or (mode == "auto" and binary) else NORMAL_MASS_GRADIENT
        self.pool_rows = max(self.pool_rows, 4 * bands + len(P) // 64)
        self._reset_boxes()  # the routing changed: the next advance() refits the box and the pool
        self.set_solo(None)
        if self.boxed:  # boxes for the new fragments (the next frame's fit adds its travel)
            if self.normal_mode == NORMAL_MASS_GRADIENT:
                self._update_centroids()
            self.boxes.fit(P.x, P.fragment, 1 + self.box_slack, self.n_fragments)
        elif self.multifield:
            self.grid.ensure_pool(self.pool_rows)
            self.grid.zero()
            if self.normal_mode == NORMAL_MASS_GRADIENT:
                self._update_centroids()
        if self._diagnostics is not None:
            self._diagnostics.on_latch()

    def clamped_count(self) -> int:
        """Particles clamped to the domain walls so far (host read)."""
        return int(self.counts[COUNT_CLAMPED].item())

    def diagnostics(self) -> dict:
        """Metrics of DESIGN.md "Diagnostics" for the current state (see `diagnostics/tracker.py`)."""
        return self.diagnostics_tracker().snapshot()

    def diagnostics_tracker(self):
        if self._diagnostics is None:
            from .diagnostics.tracker import Diagnostics

            self._diagnostics = Diagnostics(self)
        return self._diagnostics

    def sort_particles(self, mode: str = "cell") -> torch.Tensor:
        """Reorder particles for P2G's atomics (`neighbourhood.cell_order`; after a latch by cell, then
        fragment, and the latched topologies reordered with them); returns `order` (new particle i was old
        order[i]). Not after the diagnostics have started on a latched state (they index its particles)."""
        P, g = self.particles, self.grid
        if self.latched and self._diagnostics is not None:
            raise SimulationError("sort_particles must come before the diagnostics start on a latched state")
        fragment = P.fragment if self.latched else None
        order = cell_order(P.x, g.origin, g.dx, g.shape, mode, fragment)
        P.permute(order)
        if self.latched:
            self.topologies = [t.permuted(order) for t in self.topologies]
            self.topology = self.topologies[-1]
        self.p2g_run = P2G_RUN if mode == "cell" and self.device != "cpu" else 0
        self.set_solo(None)  # recomputed for the new order at the next frame
        return order
