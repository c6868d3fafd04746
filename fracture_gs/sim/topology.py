"""`Topology`: the latched interface as data (fragment ids, band, plane), saved with every run.

Who produces one is `fracture_gs.sim.providers` (oracle plane, stress-guided, replay of a saved
run); the simulator only reads it (`Simulator.latch`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch



@dataclass
class Topology:
    """O = {o_p, γ_p, n_Π, t_latch} plus the plane's point (paper Section 4.1)."""

    fragment: torch.Tensor  # [N] int32 persistent fragment id o_p ∈ {0, 1}
    band: torch.Tensor  # [N] bool/int interface-band flag γ_p
    normal: tuple  # n_Π (unit, fragment 1 on its positive side)
    point: tuple  # a point on the latched plane
    latch_time: float = 0.0  # t_latch [s]
    latch_frame: int = 0
    pair_radius: float = 1.5  # interface pairs: nearest opposite band particle within this many Δx

    @staticmethod
    def from_plane(x: torch.Tensor, point, normal, band_width: float, latch_time: float = 0.0, latch_frame: int = 0,
                   pair_radius: float = 1.5) -> "Topology":
        """Labels by the sign of the signed distance to the plane; band = |distance| < band_width [m]."""
        n = torch.tensor(normal, dtype=torch.float64)
        n = n / n.norm()
        c = torch.tensor(point, dtype=torch.float64)
        d = (x.double() - c.to(x.device)) @ n.to(x.device)
        return Topology(
            fragment=(d >= 0).to(torch.int32),
            band=(d.abs() < band_width).to(torch.int32),
            normal=tuple(float(a) for a in n),
            point=tuple(float(a) for a in c),
            latch_time=float(latch_time),
            latch_frame=int(latch_frame),
            pair_radius=float(pair_radius),
        )

    def counts(self) -> dict:
        frag = self.fragment.cpu()
        return {"fragment0": int((frag == 0).sum()), "fragment1": int((frag == 1).sum()), "band": int(self.band.cpu().bool().sum())}

    def save(self, path) -> None:
        np.savez_compressed(
            path, fragment=self.fragment.cpu().numpy().astype(np.int32), band=self.band.cpu().numpy().astype(np.uint8),
            normal=np.asarray(self.normal), point=np.asarray(self.point), latch_time=self.latch_time, latch_frame=self.latch_frame,
            pair_radius=self.pair_radius,
        )

    @staticmethod
    def load(path, device="cpu") -> "Topology":
        z = np.load(path)
        return Topology(
            fragment=torch.from_numpy(z["fragment"]).to(device), band=torch.from_numpy(z["band"].astype(np.int32)).to(device),
            normal=tuple(float(a) for a in z["normal"]), point=tuple(float(a) for a in z["point"]),
            latch_time=float(z["latch_time"]), latch_frame=int(z["latch_frame"]),
            pair_radius=float(z["pair_radius"]) if "pair_radius" in z else 1.5,
        )
