"""`Simulator`: one MLS-MPM substep per call, in the transfer variant the config names.

Per substep (Algorithm 1): particle regions → stress (plastic return, band release) → grid reset
→ P2G (shared or fragment-conditioned, any number of fragments) → grid update (normalize + gravity
per field; at multi-fragment nodes the contact projection between every pair of fields; then
boundaries) → G2P (own field only).

The simulator holds the state (particles, clock, counters, topology, contact normals) and composes the rest: the
grid storage a substep transfers through (`storage`: the dense grid and slot storage `slots`, or after a latch the
per-fragment boxes `box_storage`; one interface, `storage.Storage`), the frame runner (`runner`: substeps of a frame,
CUDA graph replay, checks and redo, the event provider; `frames.FrameRunner`) and the launch switches (`options`,
a frozen `options.SimOptions`).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import replace
from typing import Optional, get_args

import torch
import warp as wp

from ..config import MATERIALS, ParticleOrder, SimConfig
from ..runtime import StreamFork, cpu_ranges, ensure_warp, launch, range_views, run_ranges, torch_stream
from ..variants import VARIANT_NAMES, variant_spec
from .boxes.fragment_boxes import FragmentBoxes
from .boxes.storage import BoxStorage
from .clock import FrameClock, tick
from .frames import FrameRunner
from .grid.domain import check_inside, fit_grid
from .grid.fields import Grid
from .grid.slots import SlotStorage
from .neighbourhood import cell_order, fragment_centroids
from .options import P2G_RUN, SimOptions
from .particles import Particles, SimulationError
from .physics.boundary import Boundaries
from .physics.constitutive import compute_stress, lame
from .physics.contact import NORMAL_LATCHED, NORMAL_MASS_GRADIENT
from .storage import COUNT_CLAMPED, MAX_SLOTS, N_COUNTS, Storage
from .topology import Topology


def validate_sim_config(cfg: SimConfig) -> None:
    """One-sentence errors for invalid solver settings."""
    if not isinstance(cfg, SimConfig):
        from ..errors import ArgumentError

        raise ArgumentError(
            f"Simulator: cfg must be a SimConfig, got {type(cfg).__name__}; pass a config's solver settings, e.g. "
            "fracture_gs.io.load_config('bread').sim."
        )
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
            raise SimulationError(f"device '{device}' was requested but CUDA is not available here; use device='cpu'.")
        return device
    if device != "cpu":
        raise SimulationError(f"Simulator: device '{device}' is not 'cpu' or 'cuda:N'; pass device='cpu' or 'cuda:0'.")
    return device


class Simulator:
    """MLS-MPM on torch tensors with Warp kernels; `particles` is shared with the kernels. `options` (default: the
    device's, `SimOptions.for_device`) picks how the kernels launch, never what they compute."""

    MUTABLE = ("x", "v", "C", "F", "yield_stress")  # what a substep writes into the particles

    def __init__(
        self, cfg: SimConfig, particles: Particles, device="cpu", provider=None, options: Optional[SimOptions] = None
    ):
        validate_sim_config(cfg)
        if not isinstance(particles, Particles):
            from ..errors import ArgumentError

            raise ArgumentError(
                f"Simulator: particles must be Particles, got {type(particles).__name__}; build them with "
                "fracture_gs.sim.Particles.from_gaussians(gs, cfg)."
            )
        ensure_warp()
        self.cfg = cfg
        self.spec = variant_spec(cfg.variant)
        self.device = normalize_device(device)
        self.options = SimOptions.for_device(self.device, cfg.particle_order) if options is None else options
        self.particles = particles.to(self.device)
        origin, dx, shape = fit_grid(cfg, self.particles.x)
        check_inside(self.particles.x, origin, dx, shape)
        storage = cfg.grid_storage if self.spec.multifield else "none"  # one field: neither slots nor boxes
        slots = cfg.field_slots if storage == "slots" else 1  # boxes (auto) keep no slots, owner words or pool
        self.grid = Grid(origin, dx, shape, self.device, slots, cfg.max_fragments)
        self.boundaries = Boundaries(cfg.boundaries, self.device, shape, cfg.wall_cells)
        self.clock = FrameClock(self.device, len(self.boundaries.regions))
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
        self._stress_of: Optional[tuple] = None  # `stress_state()` for which `stress` already holds τ (`keep_stress`)
        self.fork = StreamFork(self.device)  # CUDA: launches beside the current stream (`options.concurrent`)
        self.counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=self.device)  # see storage.COUNT_*
        P = self.particles
        self.node_mass = float(P.mass.sum() / P.volume.sum()) * dx**3  # typical occupied-node mass ρ̄Δx³
        self.eps_m = cfg.eps_mass * self.node_mass
        self.eps_b = cfg.eps_band * self.node_mass
        mu, lam = lame(P.E.double(), P.nu.double())
        rho = (P.mass / P.volume).double()
        self.wave_speed = float(torch.sqrt((lam + 2 * mu) / rho).max())
        self.latched_normal = wp.vec3(0.0, 0.0, 0.0)  # n_Π of the first event (the latched normals)
        self.normal_mode = NORMAL_LATCHED
        self.centroids = torch.zeros(cfg.max_fragments, 3, dtype=torch.float32, device=self.device)
        self._diagnostics = None
        self.record_contact = True  # contact statistics for the diagnostics (off when timing)
        self._ranges = cpu_ranges(n) if self.device == "cpu" else None  # per-particle kernels over the CPU's cores
        self._range_counts = None  # G2P's clamp counter per range (CPU)
        self._bind()
        self.slots = SlotStorage(self)  # the dense grid; after a latch the slot storage, unless boxed
        # the fragment fields after a latch in dense boxes, one per fragment (`boxes/`), instead of slots
        boxed = storage in ("auto", "boxes")
        boxes = FragmentBoxes(shape, origin, dx, self.device, cfg.max_fragments) if boxed else None
        self.box_storage = BoxStorage(self, boxes) if boxes is not None else None
        self.runner = FrameRunner(self)

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
        self.wp["centroids"] = wp.from_torch(self.centroids, dtype=wp.vec3)
        g = self.grid
        lo = [o + (self.cfg.wall_cells - 1) * g.dx for o in g.origin]
        hi = [o + (s - self.cfg.wall_cells) * g.dx for o, s in zip(g.origin, g.shape)]
        self.lower, self.upper = wp.vec3(*lo), wp.vec3(*hi)  # G2P clamps the particles into [lower, upper]
        self.gravity = wp.vec3(*[float(a) for a in self.cfg.gravity])

    def fit_active_box(self, horizon: float) -> float:
        """Fit the grid work to where particles can be during the next `horizon` seconds ("no work on empty grid"):
        the storage's `fit` from the particles' bounding box, the distance they can travel (current speed and
        gravity) and the runner's slack. P2G counts any particle whose stencil has left it, and `advance` redoes
        such a frame with more slack. One host read, which also returns max |v| for the CFL step."""
        P = self.particles
        stats = torch.cat([P.x.min(0).values, P.x.max(0).values, P.v.norm(dim=1).max()[None]]).cpu()
        vmax = float(stats[-1])
        if not bool(torch.isfinite(stats).all()):
            return vmax  # the divergence check reports it
        travel = vmax * horizon + 0.5 * math.hypot(*self.cfg.gravity) * horizon**2
        if self.multifield and self.normal_mode == NORMAL_MASS_GRADIENT:
            self._update_centroids()
        self.storage.fit(stats[:3], stats[3:6], travel, self.runner.box_slack)
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
        return self.box_storage is not None and self.multifield

    @property
    def storage(self) -> Storage:
        """The storage a substep transfers through: the per-fragment boxes while they hold the fields, else the
        dense grid with its slots."""
        return self.box_storage if self.boxed else self.slots

    @property
    def boxes(self) -> Optional[FragmentBoxes]:
        """The per-fragment boxes' buffers (None: this simulator keeps none)."""
        return self.box_storage.boxes if self.box_storage is not None else None

    @property
    def frame_redos(self) -> int:
        """Frames redone so far (a stencil escaped its box, or the pool overflowed)."""
        return self.runner.frame_redos

    @property
    def slot_overflow(self) -> int:
        """Deposits that found no free slot, in the last frame."""
        return self.runner.slot_overflow

    @property
    def slot_overflow_total(self) -> int:
        return self.runner.slot_overflow_total

    def box_fields(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """With the boxes: a substep's fields at the current particles, as the slot storage's grid views give
        them after a substep (`BoxStorage.fields`)."""
        if not self.boxed:
            raise SimulationError("box_fields needs the fields in per-fragment boxes (after a latch, boxed storage)")
        return self.box_storage.fields()

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

    # ---- frames ---------------------------------------------------------------------------------
    def advance(self, frame_dt: float) -> int:
        """Simulate one frame (`frames.FrameRunner.advance`); returns its number of substeps."""
        return self.runner.advance(frame_dt)

    # ---- the substep ----------------------------------------------------------------------------
    def substep(self, dt: Optional[float] = None) -> None:
        """Advance by one substep Δt (default `cfg.dt`). Never syncs and allocates nothing."""
        dt = float(self.dt if dt is None else dt)
        on = self.runner.set_clock(dt, [self.time])
        with self._stream_scope():
            self.substep_launches(on)
        self.time += dt
        self.substeps += 1

    def substep_launches(self, on: Optional[list], step: int = 0) -> None:
        """Every launch of one substep, the clock's tick last. `on`: the frame's region flags (only the
        regions active in substep `step` are launched), or None to launch them all (graph capture:
        each checks the clock's table itself)."""
        R = len(self.boundaries.regions)
        active = None if on is None else on[step * R : (step + 1) * R]
        w = self.wp
        self.boundaries.apply_regions(w["x"], w["v"], len(self.particles), self.clock.view, self.device, active)
        kept, self._stress_of = self._stress_of, None
        if kept is None or kept != self.stress_state():  # else `stress` holds this state's τ (`keep_stress`)
            self.compute_stress(self.stress, commit=True)
        self.transfer()
        launch(tick, 1, [self.clock.view], self.device)

    def set_clock(self, dt: float) -> None:
        """Set the substep Δt the kernels read (for `transfer` and recorded graphs of it, e.g. benchmarks)."""
        self.runner.set_clock(float(dt), [self.time])

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
            *inputs, out_ab = range_views(arrays + [out_wp], a, b)
            self.launch(compute_stress, b - a, inputs + [release, int(commit), out_ab])

        n = len(self.particles)
        if self.device == "cpu":
            run_ranges(launch, self._ranges if self._ranges is not None else [(0, n)])
        else:
            launch(0, n)

    def stress_state(self) -> tuple:
        """What τ of the current state depends on: the frame, substep and latch counts, the band release, and each
        input array's storage and torch version (every in-place torch write bumps it; the substeps' Warp writes
        do not, but they come with a new substep count)."""
        P = self.particles
        arrays = (P.F, P.material, P.E, P.nu, P.yield_stress, P.hardening, P.alpha, P.band)
        release = self.topology.release_events if self.release else 0
        return (self.frame, self.substeps, len(self.topologies), release) + tuple(
            (t.data_ptr(), t._version) for t in arrays
        )

    def can_keep_stress(self) -> bool:
        """Whether τ computed with commit=False may stand for the next substep's (`keep_stress`): on the CPU, where
        the substeps are launched one by one (a recorded CUDA graph always computes τ), and with no plastic
        particle (models 2, 3: the substep's commit writes their return into F); not for particles made in
        `torch.inference_mode` (their tensors keep no version to tell a change by)."""
        P = self.particles
        return self.device == "cpu" and not P.F.is_inference() and int(P.material.max()) < 2

    def keep_stress(self) -> None:
        """`stress` now holds τ of the current state, computed with commit=False by a caller that may
        (`can_keep_stress`: the diagnostics' shadow transfer): the next substep takes it instead of computing the
        same numbers again, unless the state changed first (`stress_state`)."""
        self._stress_of = self.stress_state()

    def _grid_pass(self, only_fragment: int) -> None:
        """Grid reset, P2G, grid update, G2P over all particles or one fragment's (Δt from the clock)."""
        self._p2g(only_fragment)
        self._update_grid()
        self.storage.g2p(only_fragment)

    def p2g(self, dt: float, only_fragment: int = -1, target=None, multifield=None, stress=None, counts=None) -> None:
        """Reset the active fields and scatter particles into them (Eq. multifield_p2g), with substep Δt.

        `target` (a Grid), `multifield`, `stress` (a Warp view) and `counts` (a Warp int32 array)
        override the destination, the routing, the stress and the counters; the diagnostics use
        them for the per-fragment shadow transfer (through the slot storage's kernels)."""
        self.runner.set_clock(float(dt), [self.time])
        self._p2g(only_fragment, target, multifield, stress, counts)

    def update_grid(self, dt: float) -> None:
        """Normalize + gravity per active field, contact projection (full), boundaries, with substep Δt."""
        self.runner.set_clock(float(dt), [self.time])
        self._update_grid()

    def g2p(self, dt: float, only_fragment: int = -1) -> None:
        """Gather v, C, F's update and x from each particle's own field (Eq. field_g2p), with substep Δt."""
        self.runner.set_clock(float(dt), [self.time])
        self.storage.g2p(only_fragment)

    def _p2g(self, only_fragment: int = -1, target=None, multifield=None, stress=None, counts=None) -> None:
        if target is None and multifield is None and stress is None:
            self.storage.p2g(only_fragment, counts)
        else:
            self.slots.p2g(only_fragment, counts, target, multifield, stress)

    def _update_grid(self) -> None:
        self.boundaries.colliders.wall_cells = int(self.cfg.wall_cells)  # the config may change between calls
        self.storage.update()

    # ---- launches (the storages launch through these) -------------------------------------------
    def launch(self, kernel, dim, inputs: list) -> None:
        launch(kernel, dim, inputs, self.device)

    def beside(self, on: bool = True):
        """Context for launches that need nothing issued after the last join and that nothing reads before
        the next one: on a GPU with `options.concurrent` (and `on`) they go to the fork's stream
        (`runtime.StreamFork`)."""
        return self.fork if on and self.options.concurrent else contextlib.nullcontext()

    def per_range(self, launch, whole: bool) -> None:
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
            self.latched_normal = wp.vec3(*[float(a) for a in n / n.norm()])
        self.topology = topology
        self.topologies.append(topology)
        self.n_fragments = max(self.n_fragments, k + 1)
        self.grid.n_fields = self.n_fragments if self.spec.multifield else 1
        mode = self.cfg.contact.normal
        binary = len(getattr(topology, "events", ())) <= 1 and self.n_fragments <= 2
        self.normal_mode = NORMAL_LATCHED if mode == "latched" or (mode == "auto" and binary) else NORMAL_MASS_GRADIENT
        self.slots.reset(bands)  # the routing changed: the next advance() refits the grid work and the pool
        if self.multifield:
            if self.normal_mode == NORMAL_MASS_GRADIENT:
                self._update_centroids()
            self.storage.on_latch(self.runner.box_slack)
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
        order[i]). Cell order turns P2G's runs on on a GPU (`options.p2g_run`), any other order off. Not after
        the diagnostics have started on a latched state (they index its particles)."""
        P, g = self.particles, self.grid
        if self.latched and self._diagnostics is not None:
            raise SimulationError("sort_particles must come before the diagnostics start on a latched state")
        fragment = P.fragment if self.latched else None
        order = cell_order(P.x, g.origin, g.dx, g.shape, mode, fragment)
        P.permute(order)
        if self.latched:
            self.topologies = [t.permuted(order) for t in self.topologies]
            self.topology = self.topologies[-1]
        self.options = replace(self.options, p2g_run=P2G_RUN if mode == "cell" and self.device != "cpu" else 0)
        self.slots.set_solo(None)  # recomputed for the new order at the next frame
        return order
