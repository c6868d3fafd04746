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
        self._flags = None  # [N] uint8 on the frames' device: the band, interface and interior bits of this topology
        self._last_epoch = None  # the last epoch body, a uint8 tensor on the frames' device
        self._pinned = None  # a CUDA run's page-locked host buffer for each frame's one copy

    def write(self, out, rgb, drawn) -> None:
        """Record frame `out` (a `pipeline.FrameOutput`): its centres and covariances, and (when they changed) its
        colours `rgb` [N,3] in [0,1], `drawn` [N] bool, band and fragment ids. Encoded on the frame's device
        (`encode_torch`); the host gets the record's bytes with two bytes saying whether the fragments or the epoch
        changed, in one copy, and the centres only when the fragments change."""
        import torch

        from .encode_torch import frame_packed

        fragment, band = out.fragment, out.band != 0  # [N] on the frame's device
        packed = frame_packed(out.means, out.covars, self.cov_unit)  # [24 + 18N] uint8
        if self._last_topology is None:
            self._new_topology(out, fragment, band)
        body = self._epoch_body(rgb, drawn, fragment)
        if self._last_epoch is None:
            host, new_epoch = self._to_host(packed), True
        else:
            last_fragment, last_band = self._last_topology
            moved = torch.stack([(fragment != last_fragment).any(), (band != last_band).any()]).any()
            differs = (body != self._last_epoch).any()
            host = self._to_host(torch.cat([packed, torch.stack([moved, differs]).to(torch.uint8)]))
            new_topology, new_epoch, host = bool(host[-2]), bool(host[-1]), host[:-2]
            if new_topology:  # a fracture: the interface flags anew, and the epoch body with them
                self._new_topology(out, fragment, band)
                body = self._epoch_body(rgb, drawn, fragment)
                new_epoch = not torch.equal(body, self._last_epoch)
        if new_epoch:
            self.epoch += 1
            self.epochs.write(fmt.epoch_header(self.epoch, int(out.frame)) + body.cpu().numpy().tobytes())
            self.epochs.flush()
            self._last_epoch = body
        self.frames.write(fmt.frame_header(int(out.frame), self.epoch, float(out.time), host[:24].tobytes()))
        self.frames.write(host[24:])  # the body straight from the copy's buffer
        self.frames.flush()

    def _epoch_body(self, rgb, drawn, fragment):  # -> [6N] uint8 on the frames' device
        """The epoch body of these colours, drawn set and fragments under the current topology's flag bits."""
        import torch

        from .encode_torch import epoch_body

        return epoch_body(rgb, drawn.to(torch.uint8) * fmt.DRAWN + self._flags, fragment)

    def _new_topology(self, out, fragment, band) -> None:
        """The fragments or the band changed (or the first frame): which band Gaussians face another fragment (on
        the host, from the frame's centres), and the flag bits that follow from the topology."""
        import torch

        frag_host, band_host = _numpy(fragment).astype(np.int64), _numpy(band)
        faces = interface_flags(_numpy(out.means).astype(np.float32), frag_host, band_host, self.radius)
        interface = torch.from_numpy(faces).to(fragment.device)
        interior = torch.from_numpy(self.interior.astype(bool)).to(fragment.device)
        self._last_topology = (fragment.clone(), band.clone())
        u8 = torch.uint8  # drawn·DRAWN + (these): integer sums, the same bytes in any grouping
        self._flags = band.to(u8) * fmt.BAND + interface.to(u8) * fmt.INTERFACE + interior.to(u8) * fmt.INTERIOR

    def _to_host(self, t):  # [n] uint8 on any device -> numpy [n] uint8, valid until the next call
        """The bytes of `t` on the host: on CUDA through a page-locked buffer kept for the next frame (the copy
        waits for this thread's stream), elsewhere `t` itself."""
        import torch

        if t.device.type != "cuda":
            return t.numpy()
        if self._pinned is None or self._pinned.numel() < t.numel():
            self._pinned = torch.empty(t.numel(), dtype=torch.uint8, pin_memory=True)
        buf = self._pinned[: t.numel()]
        buf.copy_(t, non_blocking=True)
        torch.cuda.current_stream(t.device).synchronize()
        return buf.numpy()

    def close(self) -> None:
        self.frames.close()
        self.epochs.close()
