"""What a render-sim run reports: one `VariantSummary` per variant and the run's `RunSummary`.

A variant's summary is read off its per-frame metrics rows (`summarize`): the latch, the final opening,
the largest re-approach, stringing, mixing (counterfactual and realized), mass residuals, contact and
penetration measures, speed and the energy account (`energy_report`). The numbers after the latch sit in
`AfterLatch`, the plane-contact ones (the plane-drop scene) in `PlaneContact`; both are None when the run
has none. `as_dict` is the summary.json form, key for key as the CLI, the sweeps and the paper read it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Optional

import numpy as np

from .energy_report import energy_summary


@dataclass
class AfterLatch:
    """The run's numbers from the first latched frame on (means and maxima over those frames, or the last one)."""

    mixing_counterfactual_mean: float
    """Mean counterfactual mixing E_mix (a shared field's mixing at the same state), after the latch."""
    mixing_counterfactual_max: float
    """Largest counterfactual mixing."""
    mixing_realized_mean: float
    """Mean realized mixing: what the variant's own transfer mixed across the interface."""
    mixing_realized_max: float
    """Largest realized mixing."""
    shared_support_pct_mean: float
    """Mean share of grid nodes that two fragments' stencils both reach [%]."""
    mass_residual_max: float
    """Largest relative mass residual E_m of any field."""
    opening: float
    """Interface opening at the last frame [Δx]."""
    separated: bool
    """Whether the pieces are apart at the last frame."""
    reapproach: float
    """Largest re-approach of the interface after it opened [Δx]."""
    stringing: float
    """Mean stringing: particles bridging the gap [fraction]."""
    penetration_max: float
    """Largest fixed-plane penetration [Δx]."""
    identity_crossing_max: int
    """Most particles on the other fragment's side of the latched plane."""
    fragments: int
    """Most fragments at once."""
    fragment_crossing_max: int
    """Most particles inside another fragment (fragment-aware)."""
    fragment_penetration_max: float
    """Largest fragment-aware penetration depth [Δx]."""
    collider_crossing_max: int
    """Most particles behind a collider plane."""
    slot_overflow: int
    """Grid-slot claims that found no free slot, summed over frames."""
    first_contact_time: Optional[float]
    """When two fragments' fields first met [s] (None: never)."""
    cp_momentum_residual: Optional[float]
    """Relative momentum change of the contact projection (≈ 0: it conserves momentum)."""
    rel_normal_velocity_after: Optional[float]
    """Largest approaching normal velocity left after the projection [m/s]."""
    max_delta_vt: Optional[float]
    """Largest change of tangential velocity by the projection [m/s] (friction)."""


@dataclass
class PlaneContact:
    """Contact with a collider plane (the plane-drop scene), at the last frame."""

    plane_first_contact: Optional[float]
    """When a particle first touched the plane [s]."""
    plane_penetration: float
    """Deepest particle behind the plane [Δx]."""
    plane_max_vt_near: float
    """Largest tangential speed near the plane [m/s]."""
    plane_max_vn_post: float
    """Largest normal speed into the plane after contact [m/s]."""
    plane_momentum_residual: float
    """Relative momentum change of the plane's projection."""


@dataclass
class VariantSummary:
    """One variant's run (summary.json's `variants[i]`)."""

    variant: str
    """The variant's name (`sim.variant`)."""
    status: str
    """`ok`, or why the run stopped (`diverged at frame 12: ...`, `interrupted at frame 5`)."""
    frames: int
    """The last frame simulated."""
    substeps: int
    """Substeps simulated."""
    wall_s: float
    """Wall time of the variant's simulation and rendering [s]."""
    substeps_per_s: Optional[float]
    """Substeps per second of wall time."""
    latch: Optional[dict]
    """The first fracture event (latch frame, time, plane, counts), or None."""
    energy: Optional[dict]
    """The energy account (`energy_report.energy_summary`), or None without energy rows."""
    after_latch: Optional[AfterLatch] = None
    """The numbers after the latch (None: nothing latched)."""
    plane: Optional[PlaneContact] = None
    """Plane contact (None: no collider plane)."""
    piece_gap: Optional[float] = None
    """Gap between the two largest pieces at the end [Δx] (set by the render-sim job; None: not measured)."""
    interrupted: Optional[bool] = None
    """Whether Ctrl-C or a stop ended it (set by the render-sim job)."""

    def as_dict(self) -> dict[str, Any]:
        """The summary.json form: the fields in order, the after-latch and plane numbers inline, the job's keys
        only where the job set them."""
        out: dict[str, Any] = {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if f.name not in ("after_latch", "plane", "piece_gap", "interrupted")
        }
        for part in (self.after_latch, self.plane):
            if part is not None:
                out.update(dataclasses.asdict(part))
        for key in ("piece_gap", "interrupted"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out


@dataclass
class RunSummary:
    """A render-sim run (summary.json)."""

    name: str
    """The config's name."""
    scene: str
    """The scene: a built-in name or a splat file."""
    preset: str
    """The size preset (`small`, `paper`)."""
    device: str
    """The device of the run (the first, with several)."""
    particles: int
    """Particles simulated."""
    capture: list
    """One line per automatic choice made for a captured scene."""
    frames: int
    """Frames asked for."""
    frame_dt: float
    """Time per frame [s]."""
    variants: list[dict] = field(default_factory=list)
    """Each variant's `VariantSummary.as_dict()` in the order asked (one not run: variant, status, interrupted)."""
    interrupted: bool = False
    """Whether Ctrl-C or a stop ended the run early."""
    out_dir: str = ""
    """Where the outputs are."""
    profile: Optional[str] = None
    """The time per phase (`--profile`), also in profile.md."""

    def as_dict(self) -> dict[str, Any]:
        """The summary.json form (`profile` only in memory: profile.md holds it)."""
        out = dataclasses.asdict(self)
        out.pop("profile")
        return out


def _post(rows: list, key: str) -> list:
    return [r[key] for r in rows if r.get(key) is not None]


def summarize(variant: str, rows: list, status: str, seconds: float) -> VariantSummary:
    """A variant's summary from its metrics rows: final opening, max re-approach, mean stringing after the latch,
    mixing mean/max, max mass residual, contact metrics, penetration max, speed, energy (`energy_report`)."""
    frames = rows[-1]["frame"] if rows else 0
    substeps = rows[-1]["substeps"] if rows else 0
    summary = VariantSummary(
        variant=variant,
        status=status,
        frames=frames,
        substeps=substeps,
        wall_s=round(seconds, 3),
        substeps_per_s=round(substeps / seconds, 2) if seconds > 0 else None,
        latch=next((r["latch"] for r in rows if "latch" in r), None),
        energy=energy_summary(rows),
    )
    post = [r for r in rows if r.get("latched")]
    if post:
        last = post[-1]
        cf, real = _post(post, "mixing_counterfactual"), _post(post, "mixing_realized")
        summary.after_latch = AfterLatch(
            mixing_counterfactual_mean=float(np.mean(cf)),
            mixing_counterfactual_max=float(np.max(cf)),
            mixing_realized_mean=float(np.mean(real)),
            mixing_realized_max=float(np.max(real)),
            shared_support_pct_mean=float(np.mean(_post(post, "shared_support_pct"))),
            mass_residual_max=float(max(max(r["mass_residual"]) for r in post)),
            opening=last["opening"],
            separated=bool(last["separated"]),
            reapproach=last["reapproach"],
            stringing=float(np.mean(_post(post, "stringing"))),
            penetration_max=float(max(_post(post, "penetration"))),
            identity_crossing_max=int(max(_post(post, "identity_crossing"))),
            fragments=int(max(_post(post, "fragments") or [2])),
            fragment_crossing_max=int(max(_post(post, "fragment_crossing") or [0])),
            fragment_penetration_max=float(max(_post(post, "fragment_penetration") or [0.0])),
            collider_crossing_max=int(max(_post(post, "collider_crossing") or [0])),
            slot_overflow=int(sum(_post(post, "slot_overflow"))),
            first_contact_time=last.get("first_contact_time"),
            cp_momentum_residual=last.get("cp_momentum_residual"),
            rel_normal_velocity_after=last.get("rel_normal_velocity_after"),
            max_delta_vt=last.get("max_delta_vt"),
        )
    if rows and "plane_penetration" in rows[-1]:
        last = rows[-1]
        summary.plane = PlaneContact(**{f.name: last[f.name] for f in dataclasses.fields(PlaneContact)})
    return summary


def summary_markdown(summaries: list) -> str:
    cols = [
        ("variant", "variant"),
        ("status", "status"),
        ("latch frame", None),
        ("opening/Δx", "opening"),
        ("re-approach", "reapproach"),
        ("stringing", "stringing"),
        ("separated", "separated"),
        ("E_mix cf mean", "mixing_counterfactual_mean"),
        ("E_mix real mean", "mixing_realized_mean"),
        ("max E_m", "mass_residual_max"),
        ("pen./Δx", "penetration_max"),
        ("fragments", "fragments"),
        ("fragment crossing", "fragment_crossing_max"),
        ("slot overflow", "slot_overflow"),
        ("substeps/s", "substeps_per_s"),
    ]

    def fmt(v):
        if v is None:
            return "—"
        if isinstance(v, bool):
            return "yes" if v else "no"
        if isinstance(v, float):
            return f"{v:.3g}"
        return str(v)

    lines = ["| " + " | ".join(c for c, _ in cols) + " |", "|" + "---|" * len(cols)]
    for s in summaries:
        cells = [fmt(s.get(k)) if k else fmt((s.get("latch") or {}).get("latch_frame")) for _, k in cols]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
