"""Per-frame diagnostics (docs/DESIGN.md "Diagnostics"): the tracker that turns `metrics.py`'s device
tensors into one row of metrics.jsonl per frame, with one host read per frame (the fragment-aware
overlap runs in Warp launches, `overlap_kernels.py`, and reads nothing back).

Transfer: counterfactual and realized mixing (Eq. mixing), per-fragment mass residual (Eq.
mass_error), shared-support node percentage — from a shadow fragment-conditioned P2G of the current
state (excluded from timings). Interface: opening/Δx, re-approach, stringing, separated,
penetration, identity crossing — from interface pairs built at the first latch. Fragment-aware:
penetration between the pieces themselves, continuous (`penetration.surface_depth`, eager, its own host
read) and by voxel occupancy (`voxel_*`), particles behind a plane collider.
Contact: the statistics the grid kernels accumulate, also per fragment pair. Fragment–plane: first
contact per fragment, penetration into the plane, speeds near it, gravity-compensated momentum.
Energy: kinetic, gravitational, elastic and total (`energy.py`), and whether a driving boundary acted.
"""

from __future__ import annotations

import itertools
import math
import weakref

import torch
import warp as wp

from ...config import PlaneBoundary
from ...linalg import polar_rotation
from ...profiling import phases
from ..grid.fields import Grid
from ..physics.contact import (
    N_PAIR_STATS,
    NEVER,
    PAIR_DPX,
    PAIR_DPY,
    PAIR_DPZ,
    PAIR_FIRST_T,
    PAIR_GATED,
    PAIR_PNORM,
    STAT_DPX,
    STAT_DPZ,
    STAT_DVT,
    STAT_FIRST_T,
    STAT_GATED,
    STAT_PNORM,
    STAT_UN_AFTER,
)
from ..recorded import Recorded
from ..storage import COUNT_CLAMPED, COUNT_POOL_OVERFLOW, N_COUNTS
from . import energy as E
from . import metrics as M
from .metrics import SEPARATION, collider_packed, reapproach_ratio
from .overlap_kernels import VoxelOverlap
from .penetration import calibrate, surface_penetration, unpack_overlap

VOXEL = 0.6  # Δx: voxel edge of the voxel-occupancy overlap (`penetration.fragment_overlap`)
CROSSING = 0.1  # Δx: a particle deeper than this behind another fragment's surface is a `fragment_crossing`
COLLIDER_TOLERANCE = 0.5  # Δx: a node-based plane collider holds particles to within half a cell of the plane


class Packed:
    """Device tensors gathered during a snapshot and read back in one transfer."""

    def __init__(self):
        self.parts: list[tuple[str, torch.Tensor]] = []

    def add(self, name: str, t: torch.Tensor) -> None:
        self.parts.append((name, t.reshape(-1).double()))

    def read(self) -> dict:
        if not self.parts:
            return {}
        flat = torch.cat([t for _, t in self.parts]).tolist()  # the frame's one host read
        out, i = {}, 0
        for name, t in self.parts:
            n = t.numel()
            out[name] = flat[i : i + n]
            i += n
        return out


class Float64Particles:
    """The particles with their positions, velocities, masses, volumes, F, E and ν as float64 tensors, each
    converted once, on first use; every other attribute is the particles' own. A metric's `.double()` of a float64
    tensor is that tensor, so the metrics take this for the particles and compute the same numbers: one
    conversion per array in a snapshot instead of one per metric."""

    CONVERTED = frozenset(("x", "v", "mass", "volume", "F", "E", "nu"))

    def __init__(self, particles):
        self._particles = particles

    def __getattr__(self, name: str):
        value = getattr(self._particles, name)
        if name in self.CONVERTED:
            value = value.double()
            setattr(self, name, value)  # found in the instance from now on
        return value


class Diagnostics:
    """Tracks a simulator's metrics frame by frame (`history`) and on demand (`snapshot`)."""

    def __init__(self, sim):
        self.sim = weakref.proxy(sim)  # the simulator owns its diagnostics: no reference cycle
        self.history: list[dict] = []
        self.latch_info: dict | None = None
        self.pairs = None
        self.members = None
        self.surface_calibration = None  # `penetration.calibrate` at the latest latch: the surface measure's scales
        self.band_index = None
        self.opening0 = None
        self.open_max = -math.inf
        self.reapproach = 0.0
        self.shadow: Grid | None = None
        self.shadow_rows = 0  # pool rows the shadow transfer used last frame
        self.shadow_stress = None
        self.voxels: VoxelOverlap | None = None  # the fragment-aware overlap's tables, made at the first latch
        self.recorded = Recorded(sim.device, keep=1)  # CUDA: the particle numbers as a graph (`_particle_numbers`)
        self.recorded_slices: list = []  # (name, start, end) of each part in the recorded output
        self.first_contact_time = None
        self.contact_max = {
            "cp_momentum_residual": 0.0,
            "rel_normal_velocity_after": 0.0,
            "max_delta_vt": 0.0,
            "approach_speed": 0.0,
        }
        P = sim.particles
        self.M = float(P.mass.double().sum())
        self.P0 = M.momentum(P)
        self.t0 = sim.time
        self.planes = [b for b in sim.cfg.boundaries if isinstance(b, PlaneBoundary)]
        self.fragment_penetration = 0.0  # deepest depth behind another fragment's surface so far [Δx]
        self.pair_penetration: dict = {}  # (a, b) → deepest depth of a behind b's surface so far [Δx]
        self.plane_stats = {"first_contact": [None, None], "penetration": 0.0, "max_vt_near": 0.0, "max_vn_post": 0.0}
        self._n_topologies = 0
        self.gravity = tuple(float(a) for a in sim.cfg.gravity)
        g = sim.grid
        self.energy_reference = E.reference_point(g.origin, g.dx, g.shape, self.gravity)  # the zero of E_g [m]
        self.models = frozenset(int(m) for m in P.material.unique().tolist())  # fixed for the run: one read
        self.t_prev = sim.time  # the previous frame's end: the window the drivers are checked in
        self.rotation = None  # ((frame, substeps), R(F) [N, 3, 3] float64) of the last eager snapshot (`take_rotation`)
        self.doubles: Float64Particles | None = None  # the float64 particles of the eager snapshot under way
        if sim.latched:
            self.on_latch()

    # ---- events -------------------------------------------------------------------------------
    def on_latch(self):
        """At the first latch: interface pairs, the opening's origin, the shadow grid; at every latch:
        the band members (fixed until the next event)."""
        sim = self.sim
        P, topo = sim.particles, sim.topology
        self._n_topologies = len(sim.topologies)
        self.members = M.band_members(P.fragment, P.band)
        with torch.no_grad():  # the surface measure's scales from the particles at this latch (positions only)
            self.surface_calibration = calibrate(P.x, P.fragment, self._volume_ratio())
        self.band_index = torch.nonzero(P.band != 0).flatten()
        self.particle_mass = M.per_fragment_sum(P.mass.double(), P.fragment.long(), sim.n_fragments)  # [K], fixed
        if self.latch_info is not None:
            return
        self.pairs = M.interface_pairs(P.x, P.fragment, P.band, topo.pair_radius * sim.grid.dx)
        self.n = torch.tensor(topo.normal, dtype=torch.float64, device=P.x.device)
        self.opening0 = float(M.raw_opening(P.x, self.pairs, self.n))
        self.open_max = 0.0
        g = sim.grid
        self.shadow = Grid(
            g.origin, g.dx, g.shape, sim.device, slots=sim.cfg.field_slots, max_fragments=sim.cfg.max_fragments
        )  # per-fragment fields of the current state
        self.shadow_stress = torch.zeros_like(sim.stress)
        self.shadow_stress_wp = wp.from_torch(self.shadow_stress, dtype=wp.mat33)
        self.shadow_counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=sim.device)
        self.shadow_counts_wp = wp.from_torch(self.shadow_counts)
        counts = topo.counts()
        self.latch_info = {
            "latch_frame": topo.latch_frame,
            "latch_time": topo.latch_time,
            "point": list(topo.point),
            "normal": list(topo.normal),
            **counts,
            "interface_pairs": int(self.pairs[0].numel()),
        }

    def on_frame(self):
        with phases.section("diagnostics"):
            self._on_frame()

    def _on_frame(self):
        row = self.snapshot()
        if self.latch_info is not None and not any("latch" in r for r in self.history):
            row["latch"] = self.latch_info  # the first frame row after the latch reports it
        stats = self.sim.grid.contact_stats
        stats[:STAT_FIRST_T].zero_()  # per frame; the first contact time stays
        self.history.append(row)
        self.t_prev = self.sim.time

    # ---- the frame's numbers ----------------------------------------------------------------------
    def snapshot(self) -> dict:
        try:
            return self._snapshot()
        finally:
            self.doubles = None  # this state's: not kept past the snapshot

    def _snapshot(self) -> dict:
        sim = self.sim
        if sim.latched and (self.latch_info is None or len(sim.topologies) != self._n_topologies):
            self.on_latch()
        dev = Packed()
        for name, t in self._particle_numbers():
            dev.add(name, t)
        if sim.latched:
            self._transfer(dev)
            dev.add("stats", sim.grid.contact_stats)
            Kmax = sim.grid.pair_fragments  # only the fragments in use: K² of Kmax² rows
            K = min(sim.n_fragments, Kmax)
            dev.add("pair_stats", sim.grid.pair_stats.view(Kmax, Kmax, N_PAIR_STATS)[:K, :K])
        planes = self.planes[:1]
        h = dev.read()
        if sim.latched:
            self._transfer_again(h)
        row = {
            "frame": sim.frame,
            "time": sim.time,
            "substeps": sim.substeps,
            "dt": sim.dt,
            "latched": sim.latched,
            "clamped": int(h["clamped"][0]),
            "frame_redos": sim.frame_redos,
            "momentum": h["momentum"],
            "latches": len(sim.topologies),
        }
        row.update(self._energy_row(h))
        if sim.latched:
            pool_rows = 0 if sim.boxed else sim.slots.pool_rows  # per-fragment boxes have no pool of multi-field nodes
            row.update(fragments=sim.n_fragments, slot_overflow=sim.slot_overflow, pool_rows=pool_rows)
            row.update(self._transfer_row(h))
            row.update(self._interface_row(h))
            row.update(self._contact_row(h))
        if planes:
            row.update(self._plane_row(h))
        return row

    def _particle_numbers(self) -> list[tuple[str, torch.Tensor]]:
        """(name, device tensor) of the numbers that depend on the particles alone: momentum, the
        energies (`energy.py`), the clamped count, the interface and fragment-aware measures (after the
        latch), the plane collider's. On CUDA after the latch their ≈ 100 small launches are one recorded
        CUDA graph replayed each frame (`recorded.py`), recorded again when what it bakes in changes: a
        latch, the fragment count, the particle buffers, the band release. The same kernels: the same
        numbers."""
        sim = self.sim
        if not (sim.latched and sim.options.use_graphs and self.recorded.records):
            return self._particle_numbers_now(keep_rotation=sim.device == "cpu")
        P = sim.particles
        key = (len(sim.topologies), sim.n_fragments, sim.counts.data_ptr())
        buffers = ("x", "v", "F", "mass", "volume", "E", "nu", "material", "yield_stress", "alpha", "fragment", "band")
        key += tuple(getattr(P, k).data_ptr() for k in buffers) + (self._release(),)

        def flat() -> torch.Tensor:  # run when recording: the parts' places in the output are noted then
            parts = self._particle_numbers_now()
            ends = itertools.accumulate(t.numel() for _, t in parts)
            self.recorded_slices = [(name, end - t.numel(), end) for (name, t), end in zip(parts, ends)]
            return torch.cat([t.reshape(-1).double() for _, t in parts])

        out = self.recorded(key, flat)
        return [(name, out[a:b]) for name, a, b in self.recorded_slices]

    def _particle_numbers_now(self, keep_rotation: bool = False) -> list[tuple[str, torch.Tensor]]:
        """The numbers of `_particle_numbers`, launched now. `keep_rotation`: the energy's float64 polar rotation of
        F is kept for the frame drawn from this state (`take_rotation`); on the CPU only, where it is a tensor of
        its own (a recorded CUDA graph's outputs are overwritten at its next replay)."""
        sim = self.sim
        P = Float64Particles(sim.particles)
        if keep_rotation:  # eager: `_volume_ratio` takes its F in float64 from here
            self.doubles = P
        rotation = None
        if keep_rotation and E.FIXED_COROTATED in self.models:
            rotation = polar_rotation(P.F)  # [N, 3, 3] float64: the energy's R, and the frame's SH rotation
            self.rotation = ((sim.frame, sim.substeps), rotation)
        energy = E.energies(P, self.gravity, self.energy_reference, self._release(), self.models, rotation)
        out = [("momentum", M.momentum(P)), ("energy", energy)]
        out.append(("clamped", sim.counts[COUNT_CLAMPED]))
        if sim.latched:
            out += self._interface(P)
        frag = P.fragment if sim.latched else torch.zeros_like(P.fragment)
        for b in self.planes[:1]:
            state = M.plane_state(P.x, P.v, frag, b, sim.grid.dx, max(2, sim.n_fragments))
            out += [("plane_" + k, t) for k, t in state.items()]
        return out

    def take_rotation(self):  # -> [N, 3, 3] float64 or None
        """R(F) of the particles' current F in float64, as this state's snapshot computed it for the elastic energy
        (fixed-corotated particles, on the CPU), handed over once: the frame drawn from this state rotates its SH
        by it (`pipeline.FrameOutput.rotations`: `polar_rotation` of float32 F is this float64 R rounded once, the
        same bits), so the polar decomposition runs once per frame, not twice. None when no snapshot of this
        state (frame, substeps) computed it."""
        sim = self.sim
        kept, self.rotation = self.rotation, None
        if kept is None or kept[0] != (sim.frame, sim.substeps):
            return None
        return kept[1]

    def _release(self) -> int:
        """Band particles of events 1 … this carry no stress (0: none), as `Simulator.compute_stress`."""
        sim = self.sim
        return sim.topology.release_events if sim.release else 0

    def _energy_row(self, h: dict) -> dict:
        """Kinetic, gravitational (zero at the grid corner lowest along g), elastic and total energy [J];
        `energy_driven`: a boundary that drives motion acted in the frame (`energy.drivers_active`)."""
        sim = self.sim
        kinetic, gravity, elastic = h["energy"]
        return {
            "kinetic_energy": kinetic,
            "energy_kinetic": kinetic,
            "energy_gravity": gravity,
            "energy_elastic": elastic,
            "energy_total": kinetic + gravity + elastic,
            "energy_driven": E.drivers_active(sim.cfg.boundaries, self.t_prev, sim.time, sim.dt),
        }

    def _transfer(self, dev: Packed, rows: int = 0) -> None:
        """Fragment-conditioned P2G of the current state into the shadow grid (its pool at least the
        solver's), then the mixing and the per-fragment mass residual, all on the device."""
        sim = self.sim
        keep = sim.can_keep_stress()  # τ into the solver's buffer: its next substep takes it (`Simulator.keep_stress`)
        stress, stress_wp = (sim.stress, sim.wp["stress"]) if keep else (self.shadow_stress, self.shadow_stress_wp)
        with sim._stream_scope():
            sim.compute_stress(stress, commit=False)
            if keep:
                sim.keep_stress()
            self.shadow.n_fields = sim.n_fragments
            # the shadow claims a row at every node two fragments reach (the solver's solo particles
            # claim none), so it sizes its pool from its own last frame, not only from the solver's
            self.shadow.ensure_pool(max(rows, sim.slots.pool_rows, self.shadow_rows, 256))
            self.shadow_counts.zero_()
            sim.p2g(sim.dt, target=self.shadow, multifield=True, stress=stress_wp, counts=self.shadow_counts_wp)
            # the shadow: its fragment-conditioned P2G claims every slot (the solver's skips the claims at
            # nodes only one fragment reaches), and deposits exactly what the realized transfer does
            K = sim.n_fragments
            box = self._reach()
            if box is None:
                cf, shared, grid_mass = self.shadow.field_sums(sim.eps_m, K)
            else:
                cf, shared, grid_mass = self.shadow.field_sums_within(sim.eps_m, K, box)
        dev.add("shadow_overflow", self.shadow_counts[COUNT_POOL_OVERFLOW])
        dev.add("shadow_rows", self.shadow.rows_used())
        dev.add("mixing_cf", cf)
        dev.add("shared", shared)
        mp = self.particle_mass
        dev.add("mass_residual", (grid_mass - mp).abs() / (mp + 1e-12))

    def _reach(self) -> tuple | None:
        """A node box (x0, y0, z0, x1, y1, z1) holding every node the particles' P2G stencils reach (`stencil_base`:
        ⌊(x − origin)/Δx − ½⌋ clamped into the grid, and the two nodes past it), for `Grid.field_sums_within`: on
        the CPU from the particles' extent (a host read that waits for nothing there), two nodes wider on each side
        than the float64 bound for the kernels' float32 rounding. None (the whole grid) elsewhere, with no host
        read, and for a non-finite position."""
        g, x = self.shadow, self.sim.particles.x
        if x.device.type != "cpu" or len(x) == 0:
            return None
        extent = torch.stack([x.min(0).values, x.max(0).values]).tolist()  # [[x, y, z] min, [x, y, z] max]; NaN kept
        if not all(math.isfinite(v) for row in extent for v in row):
            return None
        base = [
            [min(max(math.floor((v - o) / g.dx - 0.5) + margin, 0), s - 3) for v, o, s in zip(row, g.origin, g.shape)]
            for row, margin in zip(extent, (-2, 2))
        ]
        return tuple(base[0]) + tuple(b + 3 for b in base[1])

    def _transfer_again(self, h: dict) -> None:
        """The rare frame whose shadow pool overflowed: grow it and redo the transfer numbers (another read)."""
        for _ in range(8):
            if h["shadow_overflow"][0] == 0:
                self.shadow_rows = max(int(h["shadow_rows"][0]), self.shadow_rows // 2)  # as the solver's pool
                return
            dev = Packed()
            self._transfer(dev, rows=2 * self.shadow.capacity)
            h.update(dev.read())

    def _transfer_row(self, h: dict) -> dict:
        sim = self.sim
        per_fragment = sim.multifield or (sim.latched and sim.spec.per_fragment_pass)
        cf = h["mixing_cf"][0]
        return {
            "mixing_counterfactual": cf,
            "mixing_realized": 0.0 if per_fragment else cf,
            "shared_support_pct": h["shared"][0],
            "mass_residual": h["mass_residual"],
        }

    def _interface(self, doubles: Float64Particles) -> list[tuple[str, torch.Tensor]]:
        sim = self.sim
        P, dx = sim.particles, sim.grid.dx
        if self.voxels is None:
            self.voxels = VoxelOverlap(len(P), P.x.device)
        x = doubles.x  # [N, 3] float64
        return [
            ("opening", M.raw_opening(x, self.pairs, self.n)),
            ("penetration", M.penetration(x, self.members, self.n, 2.0 * dx)),
            ("identity_crossing", M.identity_crossing(x, P.fragment, self.members, self.n)),
            ("stringing", M.stringing(doubles.F, self.band_index)),
            ("overlap", self.voxels.packed(P.x, P.fragment, VOXEL * dx, max(2, sim.n_fragments))),
            ("collider", collider_packed(x, self.planes, COLLIDER_TOLERANCE * dx)),
        ]

    def _interface_row(self, h: dict) -> dict:
        sim = self.sim
        dx = sim.grid.dx
        opening = (h["opening"][0] - self.opening0) / dx
        self.open_max = max(self.open_max, opening)
        self.reapproach = max(self.reapproach, reapproach_ratio(self.open_max, opening))
        overlap = unpack_overlap(list(h["overlap"]), max(2, sim.n_fragments))
        surface = self._surface()
        self.fragment_penetration = max(self.fragment_penetration, surface["depth"] / dx)
        for pair, depth in surface["pairs"].items():
            self.pair_penetration[pair] = max(self.pair_penetration.get(pair, 0.0), depth / dx)
        below, depth = int(h["collider"][0]), float(h["collider"][1])
        return {
            "opening": opening,
            "reapproach": self.reapproach,
            "stringing": h["stringing"][0],
            "separated": opening > SEPARATION,
            "penetration": h["penetration"][0] / dx,
            "identity_crossing": int(h["identity_crossing"][0]),
            "fragment_crossing": surface["crossing"],
            "fragment_penetration": surface["depth"] / dx,
            "voxel_crossing": overlap["crossing"],
            "voxel_penetration": overlap["depth"] / dx,
            "collider_crossing": below,
            "collider_depth": depth / dx,
        }

    def _surface(self) -> dict:
        """Depth of particles behind another fragment's kernel-smoothed surface (`penetration.surface_penetration`),
        scaled by the calibration taken at the latch, each particle weighted by its volume change det F (computed
        only in a frame where some particle is near another piece); `fragment_crossing` counts those deeper than
        CROSSING·Δx."""
        sim = self.sim
        P, dx = sim.particles, sim.grid.dx
        with torch.no_grad():
            return surface_penetration(P.x, P.fragment, CROSSING * dx, self.surface_calibration, self._volume_ratio)

    def _volume_ratio(self) -> torch.Tensor:  # [N] det F: each particle's current over its rest volume
        P = self.sim.particles if self.doubles is None else self.doubles  # in a snapshot: its float64 F
        return torch.linalg.det(P.F.double()).clamp_min(0.0)

    def _contact_row(self, h: dict) -> dict:
        stats = h["stats"]
        gated = stats[STAT_GATED]
        first = stats[STAT_FIRST_T]
        if first < NEVER and self.first_contact_time is None:
            self.first_contact_time = first
        out = {"contact_nodes": gated, "first_contact_time": self.first_contact_time}
        if gated > 0:
            resid = math.sqrt(sum(c * c for c in stats[STAT_DPX : STAT_DPZ + 1])) / max(stats[STAT_PNORM], 1e-30)
            cm = self.contact_max
            cm["cp_momentum_residual"] = max(cm["cp_momentum_residual"], resid)
            cm["rel_normal_velocity_after"] = max(cm["rel_normal_velocity_after"], stats[STAT_UN_AFTER])
            cm["max_delta_vt"] = max(cm["max_delta_vt"], stats[STAT_DVT])
        out.update(self.contact_max)
        out["pairs"] = self._pair_row(h["pair_stats"])
        return out

    def _pair_row(self, flat: list) -> dict:
        """Per fragment pair "a-b": first contact time, contact-projection momentum residual over the
        run, deepest depth/Δx of one behind the other's surface (pairs that touched or overlapped only)."""
        K = math.isqrt(len(flat) // N_PAIR_STATS)  # the K × K block of the fragments in use, as read
        out = {}
        for k in range(K * K):
            r = flat[k * N_PAIR_STATS : (k + 1) * N_PAIR_STATS]
            if r[PAIR_GATED] <= 0:
                continue
            resid = (r[PAIR_DPX] ** 2 + r[PAIR_DPY] ** 2 + r[PAIR_DPZ] ** 2) ** 0.5 / max(r[PAIR_PNORM], 1e-30)
            out[f"{k // K}-{k % K}"] = {
                "first_contact_time": r[PAIR_FIRST_T],
                "cp_momentum_residual": resid,
                "contact_nodes": r[PAIR_GATED],
            }
        for (a, b), depth in self.pair_penetration.items():
            key = f"{min(a, b)}-{max(a, b)}"
            out.setdefault(key, {})["penetration"] = max(out.get(key, {}).get("penetration", 0.0), depth)
        return out

    def _plane_row(self, h: dict) -> dict:
        sim = self.sim
        dx = sim.grid.dx
        st = self.plane_stats
        for k in (0, 1):
            if st["first_contact"][k] is None and h["plane_touch"][k] > 0:
                st["first_contact"][k] = sim.time
        st["penetration"] = max(st["penetration"], h["plane_penetration"][0] / dx)
        st["max_vt_near"] = max(st["max_vt_near"], h["plane_vt_near"][0])
        if any(t is not None for t in st["first_contact"]):
            st["max_vn_post"] = max(st["max_vn_post"], h["plane_vn_close"][0])
        g = [float(a) for a in sim.cfg.gravity]
        elapsed = sim.time - self.t0
        p0 = self.P0.tolist()
        expected = [p0[i] + self.M * g[i] * elapsed for i in range(3)]
        scale = self.M * math.sqrt(sum(a * a for a in g)) * elapsed
        mom_h = h["momentum"]
        resid = math.sqrt(sum((mom_h[i] - expected[i]) ** 2 for i in range(3))) / scale if scale > 0 else 0.0
        return {
            "plane_first_contact": list(st["first_contact"]),
            "plane_penetration": st["penetration"],
            "plane_max_vt_near": st["max_vt_near"],
            "plane_max_vn_post": st["max_vn_post"],
            "plane_momentum_residual": resid,
        }
