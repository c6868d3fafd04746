"""Stress-guided fracture event provider (DESIGN.md "Fracture event providers").

Once per frame: the Cauchy stress σ_p = τ_p / J_p of every particle (τ the Kirchhoff stress the
solver would use, computed without committing plasticity), its largest principal stress s_p and
direction d_p (batched `torch.linalg.eigh` on the simulation device). A particle is over-stressed
when s_p > σ_R,p (its own strength, so a material map or a weakened region decides where things
break). When at least `min_particles` are over-stressed on `persist_frames` consecutive frames the
provider returns the plane through their centroid with normal along their mean, sign-aligned
principal direction, or the least-variance axis of their positions (PCA) when those directions
disagree; every particle, visible or interior, is labelled by the sign of its signed distance.
The simulator latches the first topology a provider returns and never calls it again.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Optional

import torch

from ...config import TopologyConfig
from ...errors import SimulationError
from ...linalg import eigh_chunked
from ..topology import FractureEvent, Topology
from .cuts import RELEASE_EVENTS, finish_event, plane_cut, split_components


def principal_stress(tau: torch.Tensor, F: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Largest principal Cauchy stress and its unit direction, per particle.

    σ = sym(τ) / det F (Cauchy from Kirchhoff); eigh on float64 (ascending eigenvalues, so the
    last pair is the largest). Vectorized over particles in chunks of `linalg.EIGH_CHUNK`, on the tensors'
    device."""
    J = torch.linalg.det(F.double())  # [N]
    tau = tau.double()
    sigma = 0.5 * (tau + tau.transpose(1, 2)) / J[:, None, None]  # [N,3,3]
    # eigh fails on a single non-finite row and can overflow on huge ones: decompose σ divided by
    # the power of two nearest max|σ| (exact, so finite rows give the same bits as before) and
    # scale back; a row that is not finite (J = 0, overflowed τ) has no measurable stress and reads
    # as zero with a zero direction, so it never triggers a fracture on its own.
    finite = torch.isfinite(sigma).flatten(1).all(dim=1)  # [N]
    peak = sigma.abs().flatten(1).amax(dim=1).where(finite, 0.0)  # [N]
    scale = torch.ldexp(torch.ones_like(peak), torch.frexp(peak).exponent)  # [N] power of two, 1 for 0
    unit = torch.where(finite[:, None, None], sigma / scale[:, None, None], 0.0)
    lam, axes = eigh_chunked(unit)  # ascending, columns
    values = lam[:, -1] * scale.where(finite, 0.0)  # [N]
    vectors = axes[:, :, -1].where(finite[:, None], 0.0)  # [N,3]
    return values, vectors


def orient(n: torch.Tensor) -> torch.Tensor:
    """Unit normal with its largest-magnitude component positive (a deterministic sign: for a bar
    along x, fragment 1 = the +x side)."""
    n = n / n.norm()
    return -n if n[n.abs().argmax()] < 0 else n


def mean_direction(d: torch.Tensor) -> tuple[torch.Tensor, float]:
    """Sign-aligned mean of unit directions d [M,3] and the agreement mean |cos(d, mean)|.

    Each direction is flipped to agree with the dominant one, the leading eigenvector of the
    orientation tensor Σ d dᵀ (the sign-free mean axis), before averaging."""
    _, axes = torch.linalg.eigh(d.T @ d)  # [3], [3,3] ascending
    dominant = axes[:, -1]  # [3]
    sign = torch.where(d @ dominant >= 0, 1.0, -1.0).to(d.dtype)  # [M]
    mean = (d * sign[:, None]).sum(0)
    mean = mean / mean.norm().clamp_min(torch.finfo(mean.dtype).tiny)  # 1e-300 would round to 0 in float32
    return mean, float((d @ mean).abs().mean())


def least_variance_axis(x: torch.Tensor) -> torch.Tensor:
    """PCA: the axis along which the points x [M,3] spread least."""
    c = x - x.mean(0)
    _, axes = torch.linalg.eigh(c.T @ c)  # ascending variance
    return axes[:, 0]


def over_stressed_clusters(x: torch.Tensor, over: torch.Tensor, h: float, min_size: int) -> list:
    """Spatially separate groups of over-stressed particles (cells of size h, 26-connected), each a
    mask [N], largest first; groups smaller than `min_size` are dropped."""
    idx = torch.nonzero(over).flatten()
    if idx.numel() < 2 * min_size:
        return [over] if idx.numel() else []
    label = torch.zeros(len(x), dtype=torch.int32, device=x.device)
    labels, _, _ = split_components(x[idx], label[idx], h, 1 << 20, min_particles=1)
    out = []
    for c in torch.unique(labels).tolist():
        mask = torch.zeros_like(over)
        mask[idx[labels == c]] = True
        if int(mask.sum()) >= min_size:
            out.append(mask)
    return sorted(out, key=lambda m: -int(m.sum())) or [over]


class StressProvider:
    """Latches a plane once ≥ `min_particles` particles exceed their σ_R for `persist_frames` frames.

    Records `first_exceed_frame` (first frame any particle exceeded its σ_R), `streak` (current
    run of consecutive frames with the condition), `over_count` (over-stressed particles on the
    last evaluated frame, at the latch once latched), `latch_frame`, `used_pca`, `agreement`,
    `max_ratio` / `peak_ratio` (largest s_p / σ_R,p on the last frame / on any frame so far) and
    the latched `topology`."""

    def __init__(self, cfg: TopologyConfig):
        if cfg.min_particles < 1 or cfg.persist_frames < 1:
            raise SimulationError("topology.min_particles and topology.persist_frames must be >= 1")
        self.cfg = cfg
        self.tau: Optional[torch.Tensor] = None  # [N,3,3] Kirchhoff buffer, allocated on first call
        self.first_exceed_frame: Optional[int] = None
        self.latch_frame: Optional[int] = None
        self.streak = 0
        self.over_count = 0
        self.max_ratio = 0.0
        self.peak_ratio = 0.0
        self.used_pca = False
        self.agreement: Optional[float] = None
        self.topology: Optional[Topology] = None
        self._last_frame: Optional[int] = None
        self.events = 0  # fracture events latched so far
        self.fragment_streak: dict[int, int] = {}  # repeated fracture: frames each fragment stayed over-stressed

    def _buffer(self, sim) -> torch.Tensor:
        """The Kirchhoff stress buffer, allocated once (the particle count never changes)."""
        P = sim.particles
        if self.tau is None:
            self.tau = torch.zeros(len(P), 3, 3, dtype=torch.float32, device=P.x.device)
        elif self.tau.shape[0] != len(P) or self.tau.device != P.x.device:
            raise SimulationError(
                f"StressProvider was built for {self.tau.shape[0]} particles on {self.tau.device}; "
                f"use one provider per simulation"
            )
        return self.tau

    def over_stressed(self, sim) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(s_p > σ_R,p mask [N], directions d_p [N,3], max_p s_p/σ_R,p [] ) for the current state.

        Shadow evaluation: τ goes into the provider's own buffer with `commit=False`, so neither F
        nor any other particle state is written (the latch stays impulse-free)."""
        tau = self._buffer(sim)
        with sim._stream_scope():
            sim.compute_stress(tau, commit=False)
        P = sim.particles
        s, d = principal_stress(tau, P.F)  # [N], [N,3]
        sigma_R = P.sigma_R.double()  # [N]
        return s > sigma_R, d, (s / sigma_R.clamp_min(1e-30)).max()

    def _update_streak(self, frame: int, holds: bool) -> None:
        """Consecutive frames: a frame counts only if the previous evaluated frame was frame − 1
        (calling twice on one frame does not count twice)."""
        if not holds:
            self.streak = 0
        elif self._last_frame == frame:
            self.streak = max(self.streak, 1)
        elif self._last_frame == frame - 1:
            self.streak += 1
        else:
            self.streak = 1
        self._last_frame = frame

    def __call__(self, sim) -> Optional[Topology]:
        """Evaluate this frame; return a new Topology once the condition has persisted: the first
        latch, then (with `max_events` > 1) each repeated cut."""
        if self.events >= self.cfg.max_events:
            return None
        if self.topology is not None:
            return self._repeat(sim)
        over, d, ratio = self.over_stressed(sim)
        count, self.max_ratio = torch.stack([over.sum().double(), ratio]).tolist()  # one host sync per frame
        count = self.over_count = int(count)
        self.peak_ratio = max(self.peak_ratio, self.max_ratio)
        if count > 0 and self.first_exceed_frame is None:
            self.first_exceed_frame = sim.frame
        self._update_streak(sim.frame, count >= self.cfg.min_particles)
        if self.streak < self.cfg.persist_frames:
            return None
        if self.cfg.max_events > 1:
            groups = over_stressed_clusters(sim.particles.x, over, sim.grid.dx, self.cfg.min_particles)
            if len(groups) > 1:  # several cracks at once: one cut each, largest first
                t = self._latch(sim, groups[0], d)
                return self._cut_clusters(sim, t, groups[1 : self.cfg.max_events], d)
        return self._latch(sim, over, d)

    def _cut_clusters(self, sim, t: Topology, groups: list, d: torch.Tensor) -> Topology:
        """Further cuts in the frame of the first latch: each cluster cuts the fragment holding most of it."""
        x, width = sim.particles.x, self.cfg.band_width * sim.grid.dx
        for sel in groups:
            f = int(torch.mode(t.fragment.to(x.device)[sel].long()).values)
            point, normal = self.plane(x[sel].double(), d[sel])
            frag, band, parents, children = plane_cut(
                x,
                t.fragment.to(x.device),
                t.band.to(x.device),
                point.tolist(),
                normal.tolist(),
                width,
                sim.cfg.max_fragments,
                [f],
                tag=len(t.events) + 1,
            )
            if children:
                event = FractureEvent(
                    "plane",
                    sim.time,
                    sim.frame,
                    tuple(parents),
                    tuple(children),
                    tuple(point.tolist()),
                    tuple(normal.tolist()),
                )
                t = finish_event(sim, self.cfg, t, frag, band, event)
                self.events += 1
        self.topology = t
        return t

    def plane(self, x: torch.Tensor, d: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(point, unit normal) from the over-stressed positions x [M,3] and directions d [M,3]."""
        point = x.mean(0)
        normal, self.agreement = mean_direction(d)
        self.used_pca = self.agreement < self.cfg.direction_agreement
        if self.used_pca:
            normal = least_variance_axis(x)
        return point, orient(normal)

    def _latch(self, sim, over: torch.Tensor, d: torch.Tensor) -> Topology:
        x = sim.particles.x.double()
        point, normal = self.plane(x[over], d[over])
        self.latch_frame = sim.frame
        t = Topology.from_plane(
            sim.particles.x,
            point.tolist(),
            normal.tolist(),
            self.cfg.band_width * sim.grid.dx,
            latch_time=sim.time,
            latch_frame=sim.frame,
            pair_radius=self.cfg.pair_radius,
        )
        t.release_events = RELEASE_EVENTS[self.cfg.release]
        if self.cfg.split_components:
            first, t = t.events[0], replace(t, events=[])
            t = finish_event(sim, self.cfg, t, t.fragment, t.band, first)
        self.topology = t
        self.events = 1
        return t

    def _repeat(self, sim) -> Optional[Topology]:
        """Repeated fracture: every fragment holding ≥ `min_particles` over-stressed particles (outside
        the band, where stress is already released) for `persist_frames` frames is cut by the plane
        through them; only that fragment's particles change id. One host read per frame."""
        t = self.topology
        over, d, ratio = self.over_stressed(sim)
        fragment = sim.particles.fragment.long()
        over = over & (sim.particles.band == 0)
        K = sim.cfg.max_fragments
        counts = torch.bincount(fragment[over], minlength=K)[:K]
        host = torch.cat([counts.double(), ratio.double()[None]]).tolist()
        counts, self.max_ratio = [int(c) for c in host[:K]], host[K]
        self.peak_ratio = max(self.peak_ratio, self.max_ratio)
        due = []
        for f, c in enumerate(counts):
            self.fragment_streak[f] = self.fragment_streak.get(f, 0) + 1 if c >= self.cfg.min_particles else 0
            if self.fragment_streak[f] >= self.cfg.persist_frames:
                due.append(f)
        if not due:
            return None
        due.sort(key=lambda f: -counts[f])  # the most over-stressed piece first (events may run out)
        x = sim.particles.x
        width = self.cfg.band_width * sim.grid.dx
        frag, band = t.fragment.to(x.device), t.band.to(x.device)
        for f in due[: self.cfg.max_events - self.events]:
            sel = over & (fragment == f)
            point, normal = self.plane(x[sel].double(), d[sel])
            frag, band, parents, children = plane_cut(
                x, frag, band, point.tolist(), normal.tolist(), width, K, [f], tag=len(t.events) + 1
            )
            if not children:
                continue
            event = FractureEvent(
                "plane",
                sim.time,
                sim.frame,
                tuple(parents),
                tuple(children),
                tuple(point.tolist()),
                tuple(normal.tolist()),
            )
            t = finish_event(sim, self.cfg, t, frag, band, event)
            frag, band = t.fragment, t.band
            self.events += 1
            self.fragment_streak.clear()
        if t is self.topology:
            return None
        self.topology = t
        return t

    def summary(self) -> dict:
        """Run-summary record: latch frame/time, plane, per-fragment and band counts, detection stats."""
        out = {
            "provider": "stress",
            "latched": self.topology is not None,
            "latch_frame": self.latch_frame,
            "events": self.events,
            "first_exceed_frame": self.first_exceed_frame,
            "over_stressed": self.over_count,
            "min_particles": self.cfg.min_particles,
            "persist_frames": self.cfg.persist_frames,
            "used_pca": self.used_pca,
            "direction_agreement": self.agreement,
            "max_ratio": self.max_ratio,
            "peak_ratio": self.peak_ratio,
            "band_width": self.cfg.band_width,
        }
        if self.topology is not None:
            t = self.topology
            out.update(latch_time=t.latch_time, normal=list(t.normal), point=list(t.point), counts=t.counts())
        return out
