"""`Topology`: the fracture state as data (fragment ids, band, events), saved with every run.

A Topology is a snapshot: the labels every particle carries after some fracture events, plus the
list of those events. The first event's plane is the paper's latched interface (n_Π, point). A
run that breaks again latches a newer snapshot (repeated fracture); `save_history` writes every
snapshot of a run to one `topology.npz`, so each variant replays the same history.

Who produces one is `fracture_gs.sim.providers`; the simulator only reads it (`Simulator.latch`).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field, replace
from typing import Optional

import numpy as np
import torch


@dataclass
class FractureEvent:
    """One fracture event: which fragments it cut and which ids it created."""

    kind: str  # "plane" (a cut by a plane), "voronoi" (a shatter into cells)
    time: float  # [s]
    frame: int
    parents: tuple = ()  # fragment ids that were cut (−1: the unbroken object)
    children: tuple = ()  # fragment ids created by the event (connected components included)
    point: Optional[tuple] = None  # a point on the cutting plane (plane events)
    normal: Optional[tuple] = None  # the plane's unit normal, children on its positive side
    seeds: Optional[list] = None  # Voronoi cell sites (voronoi events)


@dataclass
class Topology:
    """O = {o_p, γ_p, n_Π, t_latch} plus the plane's point (paper Section 4.1) and the event history."""

    fragment: torch.Tensor  # [N] int32 persistent fragment id o_p ∈ {0, …, K − 1}
    band: torch.Tensor  # [N] int γ_p: 0, or the 1-based index of the event whose cut the particle lies near
    normal: tuple  # n_Π of the first event (unit, fragment 1 on its positive side)
    point: tuple  # a point on the first event's plane
    latch_time: float = 0.0  # t_latch of this snapshot [s]
    latch_frame: int = 0
    pair_radius: float = 1.5  # interface pairs: nearest opposite band particle within this many Δx
    events: list = field(default_factory=list)  # FractureEvent list, oldest first
    release_events: int = 1  # band particles of events 1 … release_events get stress release (0: none)

    @staticmethod
    def from_plane(
        x: torch.Tensor,
        point,
        normal,
        band_width: float,
        latch_time: float = 0.0,
        latch_frame: int = 0,
        pair_radius: float = 1.5,
    ) -> Topology:
        """Labels by the sign of the signed distance to the plane; band = |distance| < band_width [m]."""
        n = torch.tensor(normal, dtype=torch.float64)
        n = n / n.norm()
        c = torch.tensor(point, dtype=torch.float64)
        d = (x.double() - c.to(x.device)) @ n.to(x.device)
        normal, point = tuple(float(a) for a in n), tuple(float(a) for a in c)
        return Topology(
            fragment=(d >= 0).to(torch.int32),
            band=(d.abs() < band_width).to(torch.int32),
            normal=normal,
            point=point,
            latch_time=float(latch_time),
            latch_frame=int(latch_frame),
            pair_radius=float(pair_radius),
            events=[FractureEvent("plane", float(latch_time), int(latch_frame), (-1,), (0, 1), point, normal)],
        )

    def permuted(self, order: torch.Tensor) -> Topology:
        """The same topology for particles reordered as `Simulator.sort_particles` does (new i = old order[i])."""
        o = order.to(self.fragment.device)
        return replace(self, fragment=self.fragment[o], band=self.band[o])

    @property
    def n_fragments(self) -> int:
        return int(self.fragment.max()) + 1 if self.fragment.numel() else 0

    def counts(self) -> dict:
        frag = self.fragment.cpu()
        out = {
            "fragment0": int((frag == 0).sum()),
            "fragment1": int((frag == 1).sum()),
            "band": int(self.band.cpu().bool().sum()),
        }
        if self.n_fragments > 2:
            out["fragments"] = self.n_fragments
        return out

    def refined(self, fragment: torch.Tensor, band: torch.Tensor, event: FractureEvent) -> Topology:
        """The snapshot after one more event (labels replaced, event appended; n_Π stays the first's)."""
        return replace(
            self,
            fragment=fragment.to(torch.int32),
            band=band.to(torch.int32),
            latch_time=event.time,
            latch_frame=event.frame,
            events=list(self.events) + [event],
        )

    def _arrays(self) -> dict:
        return dict(
            fragment=self.fragment.cpu().numpy().astype(np.int32),
            band=self.band.cpu().numpy().astype(np.uint8),
            normal=np.asarray(self.normal),
            point=np.asarray(self.point),
            latch_time=self.latch_time,
            latch_frame=self.latch_frame,
            pair_radius=self.pair_radius,
            events=json.dumps([asdict(e) for e in self.events]),
            release_events=self.release_events,
        )

    def save(self, path) -> None:
        np.savez_compressed(path, **self._arrays())

    @staticmethod
    def _from_arrays(z, device, suffix: str = "") -> Topology:
        events = json.loads(str(z["events" + suffix])) if "events" + suffix in z else []
        return Topology(
            fragment=torch.from_numpy(np.asarray(z["fragment" + suffix])).to(device),
            band=torch.from_numpy(np.asarray(z["band" + suffix]).astype(np.int32)).to(device),
            normal=tuple(float(a) for a in z["normal" + suffix]),
            point=tuple(float(a) for a in z["point" + suffix]),
            latch_time=float(z["latch_time" + suffix]),
            latch_frame=int(z["latch_frame" + suffix]),
            pair_radius=float(z["pair_radius" + suffix]) if "pair_radius" + suffix in z else 1.5,
            release_events=int(z["release_events" + suffix]) if "release_events" + suffix in z else 1,
            events=[
                FractureEvent(**{k: (tuple(v) if isinstance(v, list) and k != "seeds" else v) for k, v in e.items()})
                for e in events
            ],
        )

    @staticmethod
    def load(path, device="cpu") -> Topology:
        """The last snapshot of a saved run (one file holds one snapshot or a whole history)."""
        return load_history(path, device)[-1]


def save_history(path, topologies: list) -> None:
    """Every snapshot of a run in one npz: the last one under plain names (readable as a single
    Topology), each one under names suffixed _0, _1, …"""
    arrays = dict(topologies[-1]._arrays())
    for i, t in enumerate(topologies):
        arrays.update({f"{k}_{i}": v for k, v in t._arrays().items()})
    arrays["snapshots"] = len(topologies)
    np.savez_compressed(path, **arrays)


def load_history(path, device="cpu") -> list:
    """The snapshots of a saved run, oldest first."""
    with np.load(path) as z:
        if "snapshots" not in z:
            return [Topology._from_arrays(z, device)]
        return [Topology._from_arrays(z, device, f"_{i}") for i in range(int(z["snapshots"]))]
