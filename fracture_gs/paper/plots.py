"""Figures: teaser, multi-scene grid, method slice and opening/mixing curves (matplotlib, cv2)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from ..variants import variant_spec
from .experiments import ExperimentRun
from .protocol import SCENE_NAMES

# --------------------------------------------------------------------------------------------
# figures


def _inset(img: np.ndarray, region, radius_cap: float = 40, zoom: float = 2.5) -> np.ndarray:
    """Circular magnified inset around region = (cx, cy, r) if it lies inside the image."""
    from ..render import compose

    if region is None:
        return img
    cx, cy, r = region
    if not (0 <= cx < img.shape[1] and 0 <= cy < img.shape[0]):
        return img
    r = float(np.clip(r, 8, max(8.0, min(radius_cap, min(img.shape[:2]) / 5))))
    return compose.add_inset(img, (cx, cy), r, zoom)


def teaser_figure(
    panels: dict,
    frames: Sequence[int],
    frame_dt: float,
    path,
    regions: Optional[dict] = None,
    variants: Sequence[str] = ("baseline", "full"),
    title: Optional[str] = None,
) -> np.ndarray:
    """Figure 1: rows = variants (shared-field baseline, FractureFields), columns = matched times,
    each panel with a circular inset around the latched interface. `panels[variant][frame]` are
    HxWx3 uint8 images; `regions[frame]` = (cx, cy, r) in pixels (None: no inset)."""
    from ..io.video import save_png
    from ..render import compose

    rows = []
    for v in variants:
        rows.append([_inset(panels[v][f], (regions or {}).get(f)) for f in frames])
    labels = [variant_spec(v).caption for v in variants]
    cols = [f"t = {f * frame_dt:.2f} s (frame {f})" for f in frames]
    img = compose.grid(rows, row_labels=labels, col_labels=cols)
    if title:
        img = compose.caption(img, title)
    save_png(path, img)
    return img


def multiscene_figure(
    panels: dict,
    path,
    regions: Optional[dict] = None,
    variants: Sequence[str] = ("baseline", "stress_zero", "full"),
    times: Optional[dict] = None,
) -> np.ndarray:
    """Figure 2: rows = scenes, columns = baseline / Stress-Zero / Full at one matched
    post-fracture time per scene. `panels[scene][variant]` images, `regions[scene]` inset regions,
    `times[scene]` a row-label suffix (e.g. 't = 0.89 s')."""
    from ..io.video import save_png
    from ..render import compose

    scenes = list(panels)
    rows = [[_inset(panels[s][v], (regions or {}).get(s)) for v in variants] for s in scenes]
    labels = [SCENE_NAMES.get(s, s) + (f" {times[s]}" if times and s in times else "") for s in scenes]
    img = compose.grid(rows, row_labels=labels, col_labels=[variant_spec(v).caption for v in variants])
    save_png(path, img)
    return img


def method_slice(sim, axis: int = 2, where: Optional[float] = None) -> Optional[dict]:
    """A 2D slice of a fragment-conditioned simulation's last substep (real data for the method
    figure): particles within Δx of the slice coloured by fragment and band, the slice's grid
    nodes by the set of active fields, and the contact impulse m¹(v¹₊ − v¹₋) on field 1 at every
    node the projection acted on (equal and opposite on field 0). With per-fragment boxes (emptied after
    every substep) the fields are those of a substep at the current particles (`Simulator.box_fields`).
    None before the latch or for a single-field variant."""
    if not sim.latched or sim.grid.n_fields < 2:
        return None
    P, g = sim.particles, sim.grid
    dx = g.dx
    x = P.x.detach().double().cpu().numpy()
    if where is None:
        where = float(np.median(x[:, axis]))
    k = int(round((where - g.origin[axis]) / dx))
    k = min(max(k, 0), g.shape[axis] - 1)
    plane = g.origin[axis] + k * dx
    keep = np.abs(x[:, axis] - plane) < 0.5 * dx
    a, b = [i for i in range(3) if i != axis]
    idx = [slice(None)] * 3
    idx[axis] = k
    idx = tuple(idx)
    # the last substep's fields; per-fragment boxes are emptied after each substep: a substep's at the end state
    mass, momentum, velocity, band_mass = (
        sim.box_fields() if sim.boxed else (g.mass, g.momentum, g.velocity, g.band_mass)
    )
    m = mass.detach().double().cpu().numpy()[(slice(0, 2),) + idx]  # [2, A, B]
    p = momentum.detach().double().cpu().numpy()[(slice(0, 2),) + idx]  # [2, A, B, 3]
    vpost = velocity.detach().double().cpu().numpy()[(slice(0, 2),) + idx]
    mb = band_mass.detach().double().cpu().numpy()[(slice(0, 2),) + idx]
    eps_m, eps_b = sim.eps_m, sim.eps_b
    act = m > eps_m
    grav = np.asarray(sim.cfg.gravity, dtype=np.float64)
    vpre = np.where(act[..., None], p / np.maximum(m, 1e-300)[..., None] + sim.dt * grav, 0.0)
    n = np.asarray(sim.topology.normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    gate = act[0] & act[1] & (mb[0] > eps_b) & (mb[1] > eps_b)
    un = (vpre[1] - vpre[0]) @ n
    projected = gate & (un < 0)
    impulse = m[1][..., None] * (vpost[1] - vpre[1])
    impulse[~projected] = 0.0
    category = np.zeros(m.shape[1:], np.int8)
    category[act[0] & ~act[1]] = 1
    category[act[1] & ~act[0]] = 2
    category[act[0] & act[1]] = 3
    category[projected] = 4
    ia, ib = np.nonzero(category > 0)
    nodes = np.stack([g.origin[a] + ia * dx, g.origin[b] + ib * dx], 1)
    return {
        "axes": (a, b),
        "plane": plane,
        "dx": dx,
        "time": sim.time,
        "frame": sim.frame,
        "variant": sim.cfg.variant,
        "px": x[keep][:, [a, b]],
        "fragment": P.fragment.cpu().numpy()[keep],
        "band": P.band.cpu().numpy()[keep],
        "nodes": nodes,
        "category": category[ia, ib],
        "impulse": impulse[ia, ib][:, [a, b]],
        "n_projected": int(projected.sum()),
        "normal": n[[a, b]],
        "point": np.asarray(sim.topology.point)[[a, b]],
    }


def method_figure(data: dict, path, title: Optional[str] = None, dpi: int = 110) -> None:
    """Figure (method): the slice from `method_slice` — particles by fragment (band outlined),
    nodes by active field set (fragment 0 only, 1 only, shared support, contact-projected), contact
    impulses on field 1 as arrows, the latched interface as a dashed line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 4.6), dpi=dpi)
    names = "xyz"
    a, b = data["axes"]
    nodes, cat = data["nodes"], data["category"]
    styles = {
        1: ("#f4a582", "field 0 only"),
        2: ("#92c5de", "field 1 only"),
        3: ("#7b3294", "both fields (shared support)"),
        4: ("#d7191c", "contact projected"),
    }
    for c, (col, lab) in styles.items():
        sel = cat == c
        if sel.any():
            ax.scatter(
                nodes[sel, 0],
                nodes[sel, 1],
                s=26 if c >= 3 else 14,
                marker="s",
                facecolors="none",
                edgecolors=col,
                linewidths=1.0,
                label=f"node: {lab} ({int(sel.sum())})",
                zorder=2,
            )
    px, frag, band = data["px"], data["fragment"], data["band"]
    for k, col in ((0, "#b2182b"), (1, "#2166ac")):
        sel = frag == k
        ax.scatter(px[sel, 0], px[sel, 1], s=6, c=col, label=f"particle, fragment {k}", zorder=3, linewidths=0)
        selb = sel & (band != 0)
        ax.scatter(px[selb, 0], px[selb, 1], s=16, facecolors="none", edgecolors="k", linewidths=0.4, zorder=4)
    ax.scatter([], [], s=16, facecolors="none", edgecolors="k", linewidths=0.4, label="interface band")
    imp = data["impulse"]
    mag = np.linalg.norm(imp, axis=1)
    sel = mag > 0
    if sel.any():
        scale = mag[sel].max() / (1.5 * data["dx"])
        ax.quiver(
            nodes[sel, 0],
            nodes[sel, 1],
            imp[sel, 0],
            imp[sel, 1],
            angles="xy",
            scale_units="xy",
            scale=scale,
            color="#1a9641",
            width=0.004,
            zorder=5,
            label="contact impulse on field 1",
        )
    n, c = data["normal"], data["point"]
    t = np.array([-n[1], n[0]])
    if np.linalg.norm(t) > 1e-9:
        t = t / np.linalg.norm(t)
        L = 0.5
        ax.plot(
            [c[0] - L * t[0], c[0] + L * t[0]],
            [c[1] - L * t[1], c[1] + L * t[1]],
            "k--",
            lw=0.8,
            label="latched interface Π",
        )
    lo = np.minimum(px.min(0) if len(px) else nodes.min(0), nodes.min(0)) - data["dx"]
    hi = np.maximum(px.max(0) if len(px) else nodes.max(0), nodes.max(0)) + data["dx"]
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel(f"{names[a]} [m]")
    ax.set_ylabel(f"{names[b]} [m]")
    ax.set_title(
        title
        or f"{data['variant']}: slice {names[3 - a - b]} = {data['plane']:.3f} m, t = {data['time']:.3f} s "
        f"(frame {data['frame']}), {data['n_projected']} projected nodes",
        fontsize=9,
    )
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    fig.subplots_adjust(left=0.1, right=0.66, bottom=0.1, top=0.92)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)  # fixed size: figsize × dpi
    plt.close(fig)


def curves_figure(series: dict, path, dpi: int = 100) -> None:
    """Opening/Δx and mixing (counterfactual dashed, realized solid) over time per variant;
    `series[scene][variant]` = dict(t=[...], opening=[...], cf=[...], real=[...], latch_t=float)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(series)
    colors = {
        "baseline": "#555555",
        "probe_latch": "#e6ab02",
        "stress_zero": "#1b9e77",
        "full": "#d95f02",
        "local_multifield": "#7570b3",
        "global_fragment_pass": "#66a61e",
    }
    fig, axes = plt.subplots(len(scenes), 2, figsize=(9.0, 2.8 * len(scenes)), dpi=dpi, squeeze=False)
    for i, s in enumerate(scenes):
        ax_o, ax_m = axes[i]
        for v, d in series[s].items():
            col = colors.get(v, None)
            lab = variant_spec(v).label
            ax_o.plot(d["t"], d["opening"], color=col, label=lab, lw=1.4)
            ax_m.plot(d["t"], d["real"], color=col, lw=1.4, label=f"{lab} (realized)")
            ax_m.plot(d["t"], d["cf"], color=col, lw=1.0, ls="--", label=f"{lab} (counterfactual)")
            if d.get("latch_t") is not None:
                for ax in (ax_o, ax_m):
                    ax.axvline(d["latch_t"], color="k", lw=0.6, ls=":")
        ax_o.axhline(0.1, color="k", lw=0.6, ls="--")
        ax_o.set_ylabel(f"{SCENE_NAMES.get(s, s)}\nopening / Δx")
        ax_m.set_yscale("symlog", linthresh=1e-10)
        ax_m.set_ylim(bottom=0)
        ax_m.set_ylabel("E_mix")
        for ax in (ax_o, ax_m):
            ax.set_xlabel("t [s]")
            ax.grid(alpha=0.3)
        if i == 0:
            ax_o.set_title("interface opening (dashed: 0.1Δx separation rule; dotted: latch)", fontsize=9)
            ax_m.set_title("mixing: realized (solid), counterfactual (dashed)", fontsize=9)
            ax_o.legend(fontsize=7)
    handles, labels = axes[0][1].get_legend_handles_labels()
    if handles:
        axes[0][1].legend(handles, labels, fontsize=6, ncol=1)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def curve_series(exp: ExperimentRun, variants: Sequence[str]) -> dict:
    """Per-variant time series for `curves_figure` from an experiment's rows."""
    out = {}
    for v in variants:
        if v not in exp.runs:
            continue
        rows = [r for r in exp.runs[v].rows if "opening" in r]
        out[v] = {
            "t": [r["time"] for r in rows],
            "opening": [r["opening"] for r in rows],
            "cf": [r["mixing_counterfactual"] for r in rows],
            "real": [r["mixing_realized"] for r in rows],
            "latch_t": rows[0]["time"] if rows else None,
        }
    return out
