"""Per-frame diagnostics (DESIGN.md "Diagnostics"), computed on the device with vectorized torch.

Transfer: counterfactual and realized mixing (Eq. mixing), per-fragment mass residual (Eq.
mass_error), shared-support node percentage — from a shadow fragment-conditioned P2G of the current
state (excluded from timings). Interface: opening/Δx, re-approach, stringing, separated,
penetration, identity crossing — from interface pairs built at the latch. Contact: the statistics
the grid kernel accumulates (first gate time, momentum residual, residual approach speed,
tangential change). Fragment–plane: first contact per fragment, penetration into the plane,
tangential and normal speeds near it, gravity-compensated momentum residual.
"""
from __future__ import annotations

import math

import torch
import warp as wp

from ..config import PlaneBoundary
from ..profiling import phases
from .grid import Grid
from .layout import (COUNT_POOL_OVERFLOW, N_COUNTS, N_PAIR_STATS, NEVER, PAIR_DPX, PAIR_DPY, PAIR_DPZ, PAIR_FIRST_T,
                     PAIR_GATED, PAIR_PNORM, STAT_DPX, STAT_DPZ, STAT_DVT, STAT_FIRST_T, STAT_GATED, STAT_PNORM, STAT_UN_AFTER)
from .penetration import collider_crossing, fragment_overlap

EPS = 1e-30
SEPARATION = 0.1  # Δx: an interface whose opening exceeds this has separated (DESIGN.md)
VOXEL = 0.6  # Δx: voxel edge of the fragment-aware occupied volume (`penetration.py`)
COLLIDER_TOLERANCE = 0.5  # Δx: a node-based plane collider holds particles to within half a cell of the plane


def reapproach_ratio(open_max: float, opening: float) -> float:
    """Drop of the opening below its running maximum, over that maximum (DESIGN.md), with the
    maximum floored at the separation threshold: an interface that never opened past noise level
    would otherwise divide by noise (a 0.01 Δx drop below a 0.001 Δx maximum reads 10)."""
    return max(0.0, open_max - opening) / max(open_max, SEPARATION)


def interface_pairs(x, fragment, band, radius: float, chunk: int = 2048):
    """Each band particle of fragment 0 paired with its nearest band particle of fragment 1 within
    `radius` [m]; returns index tensors (p, q)."""
    a = torch.nonzero((fragment == 0) & (band != 0)).flatten()
    b = torch.nonzero((fragment == 1) & (band != 0)).flatten()
    if a.numel() == 0 or b.numel() == 0:
        return a[:0], b[:0]
    xb = x[b].double()
    ps, qs = [], []
    for start in range(0, a.numel(), chunk):
        ia = a[start:start + chunk]
        d, j = torch.cdist(x[ia].double(), xb).min(dim=1)
        keep = d < radius
        ps.append(ia[keep])
        qs.append(b[j[keep]])
    return torch.cat(ps), torch.cat(qs)


def mixing(mass, momentum, eps_m: float, routing=(0, 0)):
    """(E_cf, E_real, shared %) from per-fragment fields m^k [2,...], p^k [2,...,3] (Eq. mixing).

    Counterfactual: Σ m^k ‖v̄ − v^k‖² / Σ m^k with v̄ = (p⁰ + p¹)/(m⁰ + m¹). Realized: v̄ replaced
    by the velocity of the field fragment k was routed to (`routing[k]`): the shared field 0 under
    shared transfer, field k itself under fragment-conditioned routing — where it is p^k/m^k and
    the term vanishes by construction."""
    m = mass.double()
    p = momentum.double()
    active = m > eps_m
    v = torch.where(active[..., None], p / m.clamp_min(EPS)[..., None], torch.zeros_like(p))
    denom = float(m.sum()) + EPS

    def discrepancy(field_of_fragment):
        total = 0.0
        for k in (0, 1):
            members = [j for j in (0, 1) if field_of_fragment[j] == field_of_fragment[k]]
            vf = sum(p[j] for j in members) / sum(m[j] for j in members).clamp_min(EPS)[..., None]
            total += float((m[k] * active[k] * ((vf - v[k]) ** 2).sum(-1)).sum())
        return total / denom

    shared = 100.0 * float((active[0] & active[1]).sum()) / max(1, int(active.any(0).sum()))
    return discrepancy((0, 0)), discrepancy(tuple(routing)), shared


def penetration(x, fragment, band, n, radius: float, chunk: int = 2048) -> float:
    """Largest overlap along n near the interface [m]: for every band particle p of fragment 0,
    how far its current neighbours q of fragment 1 (band, within `radius`) lie behind it,
    max(0, (x_p − x_q)·n). Current neighbours follow tangential sliding."""
    a = torch.nonzero((fragment == 0) & (band != 0)).flatten()
    b = torch.nonzero((fragment == 1) & (band != 0)).flatten()
    if a.numel() == 0 or b.numel() == 0:
        return 0.0
    xb, sb = x[b], x[b] @ n
    worst = torch.zeros((), dtype=x.dtype, device=x.device)
    for start in range(0, a.numel(), chunk):
        xa = x[a[start:start + chunk]]
        near = torch.cdist(xa, xb) < radius
        depth = (xa @ n)[:, None] - sb[None, :]
        worst = torch.maximum(worst, torch.where(near, depth, torch.zeros_like(depth)).max())
    return float(worst)


def identity_crossing(x, fragment, band, n) -> int:
    """Particles on the other fragment's side of the separating plane: normal n_Π, placed midway
    between the facing band fronts (max s over fragment 0's band, min s over fragment 1's) as
    they move. While the fronts have not passed each other no particle crosses; a fixed plane
    would count particles of a fragment that merely moved past where the interface used to be."""
    s = x @ n
    front0 = s[(fragment == 0) & (band != 0)]
    front1 = s[(fragment == 1) & (band != 0)]
    if front0.numel() == 0 or front1.numel() == 0:
        return 0
    mid = 0.5 * (front0.max() + front1.min())
    return int(((fragment == 0) & (s > mid)).sum() + ((fragment == 1) & (s < mid)).sum())


def stringing(F, band):
    """Mean over band particles of ln(s_max / s_min) of F's singular values."""
    sel = band != 0
    if not bool(sel.any()):
        return 0.0
    s = torch.linalg.svdvals(F[sel].double())
    return float(torch.log(s[:, 0] / s[:, 2].clamp_min(1e-12)).mean())


class Diagnostics:
    """Tracks a simulator's metrics frame by frame (`history`) and on demand (`snapshot`)."""

    def __init__(self, sim):
        self.sim = sim
        self.history: list[dict] = []
        self.latch_info: dict | None = None
        self.pairs = None
        self.opening0 = None
        self.open_max = -math.inf
        self.reapproach = 0.0
        self.shadow: Grid | None = None
        self.shadow_stress = None
        self.first_contact_time = None
        self.contact_max = {"cp_momentum_residual": 0.0, "rel_normal_velocity_after": 0.0, "max_delta_vt": 0.0,
                            "approach_speed": 0.0}
        P = sim.particles
        self.M = float(P.mass.double().sum())
        self.P0 = (P.mass.double()[:, None] * P.v.double()).sum(0)
        self.t0 = sim.time
        self.planes = [b for b in sim.cfg.boundaries if isinstance(b, PlaneBoundary)]
        self.fragment_penetration = 0.0  # deepest fragment-aware penetration so far [Δx]
        self.pair_penetration: dict = {}  # (a, b) → deepest penetration of a into b so far [Δx]
        self.plane_stats = {"first_contact": [None, None], "penetration": 0.0, "max_vt_near": 0.0, "max_vn_post": 0.0}
        if sim.latched:
            self.on_latch()

    # ---- events -------------------------------------------------------------------------------
    def on_latch(self):
        sim = self.sim
        P, topo = sim.particles, sim.topology
        self.pairs = interface_pairs(P.x, P.fragment, P.band, topo.pair_radius * sim.grid.dx)
        self.n = torch.tensor(topo.normal, dtype=torch.float64, device=P.x.device)
        self.latch_substeps = sim.substeps
        self.opening0 = self._raw_opening()
        self.open_max = 0.0
        g = sim.grid
        self.shadow = Grid(g.origin, g.dx, g.shape, sim.device, slots=sim.cfg.field_slots,
                           max_fragments=sim.cfg.max_fragments)  # per-fragment fields of the current state
        self.shadow_stress = torch.zeros_like(sim.stress)
        self.shadow_stress_wp = wp.from_torch(self.shadow_stress, dtype=wp.mat33)
        self.shadow_counts = torch.zeros(N_COUNTS, dtype=torch.int32, device=sim.device)
        counts = topo.counts()
        self.latch_info = {"latch_frame": topo.latch_frame, "latch_time": topo.latch_time, "point": list(topo.point),
                           "normal": list(topo.normal), **counts, "interface_pairs": int(self.pairs[0].numel())}

    def on_frame(self):
        with phases.section("diagnostics"):
            self._on_frame()

    def _on_frame(self):
        row = self.snapshot()
        if self.latch_info is not None and not any("latch" in r for r in self.history):
            row["latch"] = self.latch_info  # the first frame row after the latch reports it
        stats = self.sim.grid.contact_stats
        first = float(stats[STAT_FIRST_T])
        stats.zero_()
        stats[STAT_FIRST_T] = NEVER if first >= NEVER else first
        self.history.append(row)

    # ---- metrics ------------------------------------------------------------------------------
    def _raw_opening(self):
        p, q = self.pairs
        if p.numel() == 0:
            return 0.0
        x = self.sim.particles.x.double()
        return float(((x[q] - x[p]) @ self.n).mean())

    def snapshot(self) -> dict:
        sim = self.sim
        P = sim.particles
        mom = (P.mass.double()[:, None] * P.v.double()).sum(0)
        row = {"frame": sim.frame, "time": sim.time, "substeps": sim.substeps, "dt": sim.dt, "latched": sim.latched,
               "clamped": sim.clamped_count(), "frame_redos": sim.frame_redos, "momentum": mom.tolist(),
               "kinetic_energy": float(0.5 * (P.mass.double() * (P.v.double() ** 2).sum(1)).sum())}
        if sim.latched:
            row.update(fragments=sim.n_fragments, slot_overflow=sim.slot_overflow, pool_rows=sim.pool_rows)
            if self.latch_info is None:
                self.on_latch()
            row.update(self._transfer_metrics())
            row.update(self._interface_metrics())
            row.update(self._contact_metrics())
        if self.planes:
            row.update(self._plane_metrics(mom))
        return row

    def _shadow_p2g(self) -> None:
        """Fragment-conditioned P2G of the current state into the shadow grid (its pool grown until
        nothing overflows), for the counterfactual mixing of any variant."""
        sim = self.sim
        sim.compute_stress(self.shadow_stress, commit=False)
        self.shadow.n_fields = sim.n_fragments
        rows = max(sim.pool_rows, 256)
        for _ in range(8):
            self.shadow.ensure_pool(rows)
            self.shadow_counts.zero_()
            sim.p2g(sim.dt, target=self.shadow, multifield=True, stress=self.shadow_stress_wp,
                    counts=wp.from_torch(self.shadow_counts))
            if int(self.shadow_counts[COUNT_POOL_OVERFLOW]) == 0:
                return
            rows = 2 * self.shadow.capacity

    def _transfer_metrics(self) -> dict:
        sim = self.sim
        with sim._stream_scope():
            self._shadow_p2g()
        per_fragment = sim.multifield or (sim.latched and sim.spec.per_fragment_pass)
        cf, shared = self.shadow.mixing(sim.eps_m)
        real = 0.0 if per_fragment else cf
        # the realized fields once a fragment-conditioned P2G has run, else the shadow (same kernel)
        source = sim.grid if sim.multifield and sim.substeps > self.latch_substeps else self.shadow
        K = sim.n_fragments
        P = sim.particles
        mp = torch.zeros(K, dtype=torch.float64, device=P.x.device).index_add_(0, P.fragment.long(), P.mass.double())
        mg = source.fragment_mass(K)
        residual = ((mg - mp).abs() / (mp + 1e-12)).tolist()
        return {"mixing_counterfactual": cf, "mixing_realized": real, "shared_support_pct": shared,
                "mass_residual": residual}

    def _interface_metrics(self) -> dict:
        sim = self.sim
        dx = sim.grid.dx
        P = sim.particles
        opening = (self._raw_opening() - self.opening0) / dx
        self.open_max = max(self.open_max, opening)
        self.reapproach = max(self.reapproach, reapproach_ratio(self.open_max, opening))
        x = P.x.double()
        pen = penetration(x, P.fragment, P.band, self.n, 2.0 * dx) / dx
        crossing = identity_crossing(x, P.fragment, P.band, self.n)
        overlap = fragment_overlap(P.x, P.fragment, VOXEL * dx)
        self.fragment_penetration = max(self.fragment_penetration, overlap["depth"] / dx)
        for pair, depth in overlap["pairs"].items():
            self.pair_penetration[pair] = max(self.pair_penetration.get(pair, 0.0), depth / dx)
        below, depth = collider_crossing(P.x, self.planes, COLLIDER_TOLERANCE * dx)
        return {"opening": opening, "reapproach": self.reapproach, "stringing": stringing(P.F, P.band),
                "separated": opening > SEPARATION, "penetration": pen, "identity_crossing": crossing,
                "fragment_crossing": overlap["crossing"], "fragment_penetration": overlap["depth"] / dx,
                "collider_crossing": below, "collider_depth": depth / dx}

    def _contact_metrics(self) -> dict:
        stats = self.sim.grid.contact_stats.double().cpu()
        gated = float(stats[STAT_GATED])
        first = float(stats[STAT_FIRST_T])
        if first < NEVER and self.first_contact_time is None:
            self.first_contact_time = first
        out = {"contact_nodes": gated, "first_contact_time": self.first_contact_time}
        if gated > 0:
            resid = float(stats[STAT_DPX:STAT_DPZ + 1].norm()) / max(float(stats[STAT_PNORM]), 1e-30)
            cm = self.contact_max
            cm["cp_momentum_residual"] = max(cm["cp_momentum_residual"], resid)
            cm["rel_normal_velocity_after"] = max(cm["rel_normal_velocity_after"], float(stats[STAT_UN_AFTER]))
            cm["max_delta_vt"] = max(cm["max_delta_vt"], float(stats[STAT_DVT]))
        out.update(self.contact_max)
        out["pairs"] = self._pair_metrics()
        return out

    def _pair_metrics(self) -> dict:
        """Per fragment pair "a-b": first contact time, contact-projection momentum residual over the
        run, deepest fragment-aware penetration/Δx (pairs that touched or overlapped only)."""
        g = self.sim.grid
        K = g.max_fragments
        stats = g.pair_stats.view(K * K, N_PAIR_STATS).double()
        touched = torch.nonzero(stats[:, PAIR_GATED] > 0).flatten()
        rows = stats[touched].cpu().tolist()
        out = {}
        for k, r in zip(touched.tolist(), rows):
            resid = (r[PAIR_DPX] ** 2 + r[PAIR_DPY] ** 2 + r[PAIR_DPZ] ** 2) ** 0.5 / max(r[PAIR_PNORM], 1e-30)
            out[f"{k // K}-{k % K}"] = {"first_contact_time": r[PAIR_FIRST_T], "cp_momentum_residual": resid,
                                        "contact_nodes": r[PAIR_GATED]}
        for (a, b), depth in self.pair_penetration.items():
            key = f"{min(a, b)}-{max(a, b)}"
            out.setdefault(key, {})["penetration"] = max(out.get(key, {}).get("penetration", 0.0), depth)
        return out

    def _plane_metrics(self, mom) -> dict:
        sim = self.sim
        P = sim.particles
        plane = self.planes[0]
        n = torch.tensor(plane.normal, dtype=torch.float64, device=P.x.device)
        n = n / n.norm()
        d = (P.x.double() - torch.tensor(plane.point, dtype=torch.float64, device=P.x.device)) @ n
        dx = sim.grid.dx
        st = self.plane_stats
        frag = P.fragment if sim.latched else torch.zeros_like(P.fragment)
        near = d < dx
        for k in (0, 1):
            sel = frag == k
            if st["first_contact"][k] is None and bool((near & sel).any()):
                st["first_contact"][k] = sim.time
        st["penetration"] = max(st["penetration"], float((-d).clamp_min(0).max()) / dx)
        v = P.v.double()
        vn = v @ n
        vt = (v - vn[:, None] * n).norm(dim=1)
        if bool(near.any()):
            st["max_vt_near"] = max(st["max_vt_near"], float(vt[near].max()))
        if any(t is not None for t in st["first_contact"]):
            close = d < 2 * dx
            if bool(close.any()):
                st["max_vn_post"] = max(st["max_vn_post"], float(vn[close].abs().max()))
        g = torch.tensor(sim.cfg.gravity, dtype=torch.float64, device=P.x.device)
        elapsed = sim.time - self.t0
        expected = self.P0 + self.M * g * elapsed
        scale = self.M * float(g.norm()) * elapsed
        resid = float((mom - expected).norm()) / scale if scale > 0 else 0.0
        return {"plane_first_contact": list(st["first_contact"]), "plane_penetration": st["penetration"],
                "plane_max_vt_near": st["max_vt_near"], "plane_max_vn_post": st["max_vn_post"],
                "plane_momentum_residual": resid}
