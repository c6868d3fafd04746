"""Writing a run's view record (`RUN_DIR/view/`, layout in `format`): the header once, then each variant's frames.

`start_record` is called by the render-sim job after the scene is prepared; each variant's frame sink owns a
`FrameRecorder` and hands it every frame it draws, with the colours and visibility the video used. Everything is
appended and flushed frame by frame, so Ctrl-C or a crash keeps every frame drawn so far viewable.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

import numpy as np

from .. import __version__
from . import format as fmt

FOLDER = "view"


def _numpy(t) -> np.ndarray:
    """A torch tensor (any device) or array as a numpy array."""
    if hasattr(t, "detach"):
        t = t.detach().cpu().numpy()
    return np.asarray(t)


def dc_rgb(sh) -> np.ndarray:  # [N,K,3] -> [N,3]
    """Colours from the SH DC coefficient: 0.5 + C0·dc, clipped to [0, 1] (SH degree 0)."""
    from ..sh import SH_C0

    return np.clip(_numpy(sh)[:, 0, :].astype(np.float64) * SH_C0 + 0.5, 0.0, 1.0)


def start_record(out_dir, cfg, gaussians, background, variants) -> Path:
    """Write RUN_DIR/view/ index.json and static.npz for a run of `variants` over `gaussians` (the simulated
    set, a `GaussianSet`) with `background` (a capture's static Gaussians, or None), and remove frames a previous
    run left there. Returns the folder each variant's `FrameRecorder` writes into."""
    folder = Path(out_dir) / FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    for old in list(folder.glob("*" + fmt.FRAMES_SUFFIX)) + list(folder.glob("*" + fmt.EPOCHS_SUFFIX)):
        old.unlink()
    index = folder / fmt.INDEX
    if index.exists():
        index.unlink()  # the folder holds no header until the new one is whole
    cov0 = _numpy(gaussians.covariances()).astype(np.float64)  # [N,3,3]
    variance = np.trace(cov0, axis1=1, axis2=2) / 3  # [N]
    variance = variance[np.isfinite(variance) & (variance > 0)]
    cov_unit = float(np.median(variance)) if len(variance) else 1e-6
    static = {
        "opacity": np.rint(np.clip(_numpy(gaussians.opacities), 0, 1) * 255).astype(np.uint8),
        "interior": _numpy(gaussians.interior).astype(bool),
    }
    if background is not None and len(background):
        static["background_means"] = _numpy(background.means).astype(np.float32)
        bcov = fmt.covariance_triu(_numpy(background.covariances()).astype(np.float64)) / cov_unit
        static["background_cov"] = np.clip(bcov, -fmt.F16_CLIP, fmt.F16_CLIP).astype(np.float16)
        static["background_rgb"] = np.rint(dc_rgb(background.sh) * 255).astype(np.uint8)
        static["background_opacity"] = np.rint(np.clip(_numpy(background.opacities), 0, 1) * 255).astype(np.uint8)
    np.savez(folder / fmt.STATIC, **static)
    cam = cfg.render.camera
    header = {
        "format": fmt.FORMAT,
        "version": fmt.VERSION,
        "writer": f"fracture-gs {__version__}",
        "name": cfg.name,
        "scene": cfg.scene,
        "variants": list(variants),
        "gaussians": len(gaussians),
        "background": int(len(background)) if background is not None else 0,
        "frames": int(cfg.frames),
        "frame_dt": float(cfg.frame_dt),
        "fps": int(cfg.render.fps),
        "cov_unit": cov_unit,
        "interface_radius": float(cfg.topology.pair_radius * cfg.sim.dx),
        "background_rgb": [float(c) for c in cfg.render.background],
        "camera": {
            "eye": [float(v) for v in cam.eye],
            "target": [float(v) for v in cam.target],
            "up": [float(v) for v in cam.up],
            "fov_deg": float(cam.fov_deg),
            "orbit_degrees": float(cam.orbit_degrees),
            "width": int(cfg.render.width),
            "height": int(cfg.render.height),
        },
    }
    tmp = folder / (fmt.INDEX + ".tmp")
    tmp.write_text(json.dumps(header, indent=1))
    os.replace(tmp, index)
    return folder


def interface_flags(means: np.ndarray, fragment: np.ndarray, band: np.ndarray, radius: float) -> np.ndarray:
    """[N] bool: band Gaussians that have a band Gaussian of another fragment within `radius` [m] (the two
    faces of a crack)."""
    out = np.zeros(len(means), bool)
    pick = np.nonzero(band & (fragment >= 0))[0]
    if len(pick) < 2 or radius <= 0:
        return out
    from scipy.spatial import cKDTree

    tree = cKDTree(means[pick])
    k = min(9, len(pick))
    _, idx = tree.query(means[pick], k=k, distance_upper_bound=radius)  # [M,k]; len(pick) where none
    found = idx < len(pick)
    other = np.where(found, fragment[pick][np.minimum(idx, len(pick) - 1)], fragment[pick][:, None])
    out[pick] = (other != fragment[pick][:, None]).any(1)
    return out


class FrameRecorder:
    """Appends one variant's frames to RUN_DIR/view/<variant>.frames (and a new epoch record to .epochs whenever
    the colours, visibility, band or fragments change). Used from one thread, the variant's frame sink."""

    def __init__(self, folder: Path, variant: str):
        folder = Path(folder)
        header = json.loads((folder / fmt.INDEX).read_text())
        with np.load(folder / fmt.STATIC) as static:
            self.interior = static["interior"]
        self.n, self.cov_unit = int(header["gaussians"]), float(header["cov_unit"])
        self.radius = float(header["interface_radius"])
        self.frames = open(folder / f"{variant}{fmt.FRAMES_SUFFIX}", "ab")
        self.epochs = open(folder / f"{variant}{fmt.EPOCHS_SUFFIX}", "ab")
        self.epoch = -1
        self._last_topology: Optional[tuple] = None  # (fragment, band) tensors of the last frame
        self._interface = None  # [N] bool on the frames' device: band Gaussians facing another fragment
        self._interior_dev = None
        self._last_epoch = None  # the last epoch body, a uint8 tensor on the frames' device

    def write(self, out, rgb, drawn) -> None:
        """Record frame `out` (a `pipeline.FrameOutput`): its centres and covariances, and (when they changed) its
        colours `rgb` [N,3] in [0,1], `drawn` [N] bool, band and fragment ids. Encoded on the frame's device
        (`encode_torch`); the host gets the record's bytes, and the centres only when the fragments change."""
        import torch

        from .encode_torch import epoch_body, frame_body

        fragment, band = out.fragment, out.band != 0  # [N] on the frame's device
        if self._last_topology is None or not (
            torch.equal(fragment, self._last_topology[0]) and torch.equal(band, self._last_topology[1])
        ):
            frag_host, band_host = _numpy(fragment).astype(np.int64), _numpy(band)
            faces = interface_flags(_numpy(out.means).astype(np.float32), frag_host, band_host, self.radius)
            self._interface = torch.from_numpy(faces).to(fragment.device)
            self._last_topology = (fragment.clone(), band.clone())
        if self._interior_dev is None or self._interior_dev.device != fragment.device:
            self._interior_dev = torch.from_numpy(self.interior.astype(bool)).to(fragment.device)
        flags = (
            drawn.to(torch.uint8) * fmt.DRAWN
            + band.to(torch.uint8) * fmt.BAND
            + self._interface.to(torch.uint8) * fmt.INTERFACE
            + self._interior_dev.to(torch.uint8) * fmt.INTERIOR
        )
        body = epoch_body(rgb, flags, fragment)
        if self._last_epoch is None or not torch.equal(body, self._last_epoch):
            self.epoch += 1
            self.epochs.write(fmt.epoch_header(self.epoch, int(out.frame)) + body.cpu().numpy().tobytes())
            self.epochs.flush()
            self._last_epoch = body
        box, data = frame_body(out.means, out.covars, self.cov_unit)
        self.frames.write(fmt.frame_header(int(out.frame), self.epoch, float(out.time), box) + data)
        self.frames.flush()

    def close(self) -> None:
        self.frames.close()
        self.epochs.close()
