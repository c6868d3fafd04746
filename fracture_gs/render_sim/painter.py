"""The painter of a render-sim run: a frame's Gaussians to an image (rest covariances, SH, visibility).

The interior Gaussians that fill a solid stay hidden until a fracture exposes them; then they take the
nearest surface's colour (or the material's, `render.interior_color`). With `render.color_by = "fragment"`
each piece is drawn in its own hue. One `Painter` per scene; `for_variant` gives each variant its own
exposed-interior state over the shared tensors. On CUDA a variant's frames also stay on the device
(`DrawnFrame.device_image`) for the comparison composer (`render.compose_torch`), within `DEVICE_FRAMES_BYTES`.
"""

from __future__ import annotations

import copy
from typing import Optional

import numpy as np
import torch

from ..config import SceneConfig
from ..pipeline import FrameOutput
from ..render.camera import frame_camera
from ..render.gaussians import exposed_interior_colors, sh_colors
from ..render.splat import render
from ..sh import SH_C0

DEVICE_FRAMES_BYTES = 1 << 30
"""A CUDA run keeps its drawn frames on the device too (every variant's, for the comparison composer) when they
take at most this many bytes (frames + 1 × variants × width × height × 3: the bread paper preset at 320 × 240,
3 variants and 91 frames, 63 MB); a larger run keeps them on the host only and the composer uploads its panels."""


class DrawnFrame(np.ndarray):
    """A drawn frame on the host ([H, W, 3] uint8: what the variant's video, `np.stack` and every numpy reader
    get) that also holds the same image on the renderer's device, `device_image`, so the comparison composer
    reads it there instead of uploading it. A view or slice of it is not the whole image: its `device_image` is
    None."""

    device_image: Optional[torch.Tensor] = None

    @classmethod
    def of(cls, image: torch.Tensor) -> DrawnFrame:
        """The host copy of `image` ([H, W, 3] uint8 on a device), holding `image`. The copy waits for the
        stream that drew it, so `image` is complete once this returns (other streams may read it)."""
        frame = image.cpu().numpy().view(cls)
        frame.device_image = image
        return frame


class Painter:
    """Per-scene render state: rest covariances, SH, visibility (interior hidden until exposed)."""

    def __init__(self, gs, cfg: SceneConfig, device: str, background=None):
        self.cfg, self.scene_cfg = cfg.render, cfg
        self.background = None
        if background is not None and len(background):  # static Gaussians outside the simulated region
            bg = background.to(device)
            self.background = (bg.means.float(), bg.covariances().float(), bg.sh.float(), bg.opacities.float())
        self.cov0 = gs.covariances().to(device, torch.float32)
        self.sh = gs.sh.to(device, torch.float32)
        self.opacities = gs.opacities.to(device, torch.float32)
        self.interior = gs.interior.to(device)
        self.surface_dc = (gs.sh[:, 0, :] * SH_C0 + 0.5).clamp(0, 1).to(device, torch.float32)
        self.exposed_rgb: Optional[torch.Tensor] = None
        self.exposed_count = 0
        self._visible_version: Optional[int] = None  # the topology version `_keep` was made for
        self._keep: Optional[torch.Tensor] = None
        self.keep_on_device = False  # a variant's painter on CUDA: frames as `DrawnFrame`s (`for_variant`)
        self._camera: Optional[tuple] = None  # (frame, or None for every frame; its camera) of `camera`

    def for_variant(self) -> Painter:
        """A painter for one variant's frames: the scene's tensors shared (read only), the exposed-interior
        colours its own (they follow that variant's fracture, not the previous variant's last frame)."""
        painter = copy.copy(self)
        painter.exposed_rgb, painter.exposed_count = None, 0
        painter._visible_version, painter._keep = None, None
        painter.keep_on_device = self._frames_fit_device()
        return painter

    def _frames_fit_device(self) -> bool:
        """Whether this run's drawn frames, every variant's, fit `DEVICE_FRAMES_BYTES` on a CUDA device."""
        if self.cov0.device.type != "cuda":
            return False
        cfg = self.scene_cfg
        frames = (cfg.frames + 1) * max(1, len(cfg.variants)) * cfg.render.width * cfg.render.height * 3
        return frames <= DEVICE_FRAMES_BYTES

    def camera(self, frame: int):
        """The frame's camera (`render.camera.frame_camera`); one that does not orbit is the same for every frame,
        so it is made once."""
        key = frame if self.cfg.camera.orbit_degrees else None
        if self._camera is None or self._camera[0] != key:
            self._camera = (key, frame_camera(self.scene_cfg, frame))
        return self._camera[1]

    def _visible(self, out: FrameOutput) -> torch.Tensor:
        """Indices of the Gaussians drawn: the surface, and the interior a cut has exposed. Recomputed when
        the frame's topology changed (`FrameOutput.topology_version`; −1, unknown: every frame), so a
        frame draws without reading anything back from the device."""
        version = out.topology_version
        if version < 0 or version != self._visible_version:
            exposed = self._exposed(out)
            self._keep = torch.nonzero(~self.interior | exposed).flatten()
            self._visible_version = version
        assert self._keep is not None
        return self._keep

    def _exposed(self, out: FrameOutput) -> torch.Tensor:
        if not self.cfg.show_exposed_interior or not bool((out.fragment >= 0).any()):
            return torch.zeros_like(self.interior)
        exposed = self.interior & (out.band != 0)
        count = int(exposed.sum())
        material = self.cfg.interior_color == "material"
        if count != self.exposed_count and count > 0 and (material or bool((~self.interior).any())):
            # computed when a fracture exposes new interior: the material's own colour, or the nearest surface's
            if material:
                rgb = torch.tensor(self.cfg.interior_rgb, dtype=torch.float32, device=out.means.device)
                self.exposed_rgb = rgb.expand(count, 3)
            else:
                self.exposed_rgb = exposed_interior_colors(
                    out.means[exposed], out.means[~self.interior], self.surface_dc[~self.interior]
                )
            self.exposed_idx = torch.nonzero(exposed).flatten()
            self.exposed_count = count
        return exposed

    def _fragment_colors(self, colors: torch.Tensor, fragment: torch.Tensor) -> torch.Tensor:  # [N,3] -> [N,3]
        """Each fragment in its own hue (golden-ratio spacing), shaded by the Gaussian's own brightness."""
        k = fragment.clamp_min(0).to(torch.float32)
        hue = torch.remainder(0.61803398875 * k + 0.08, 1.0)
        phase = torch.arange(3, device=k.device, dtype=torch.float32) / 3  # [0, 1/3, 2/3], no host copy
        rgb = 0.5 + 0.45 * torch.cos(2 * torch.pi * (hue[:, None] + phase))
        shade = 0.55 + 0.45 * colors.mean(1, keepdim=True).clamp(0, 1)
        return torch.where((fragment >= 0)[:, None], rgb * shade, colors)

    def view_colors(self, out: FrameOutput) -> tuple[torch.Tensor, torch.Tensor]:  # -> [N,3] in [0,1], [N] bool
        """For the viewer's record, after drawing `out`: each Gaussian's SH-DC colour (exposed interior in the colour
        the frame drew it) and whether the frame drew it."""
        rgb = self.surface_dc.clone()
        if self.exposed_rgb is not None:
            rgb[self.exposed_idx] = self.exposed_rgb
        drawn = torch.zeros(len(rgb), dtype=torch.bool, device=rgb.device)
        drawn[self._visible(out)] = True
        return rgb, drawn

    def __call__(self, out: FrameOutput) -> np.ndarray:  # -> [H, W, 3] uint8
        """The frame drawn, on the host; for a variant's painter on CUDA (`for_variant`) a `DrawnFrame`, which also
        keeps the image on the device for the comparison composer."""
        image = self.draw(out)
        return DrawnFrame.of(image) if self.keep_on_device else image.cpu().numpy()

    def draw(self, out: FrameOutput) -> torch.Tensor:  # -> [H, W, 3] uint8 on the frame's device
        """The frame drawn, on the device it was drawn on."""
        cam = self.camera(out.frame)
        keep = self._visible(out)  # [M] indices
        # SH colours of the drawn Gaussians only (each row's numbers do not depend on the others; most of a solid's
        # Gaussians are hidden interior): the rest stay 0 and are never drawn
        colors = self.sh.new_zeros(len(self.sh), 3)  # [N, 3]
        colors[keep] = sh_colors(
            self.sh.index_select(0, keep),
            out.means.index_select(0, keep),
            cam.campos.to(out.means),
            out.rotations.index_select(0, keep),
        )
        if self.exposed_rgb is not None:
            colors[self.exposed_idx] = self.exposed_rgb
        if self.cfg.color_by == "fragment":
            colors = self._fragment_colors(colors, out.fragment)
        means, covars, colors, opacities = (
            t.index_select(0, keep) for t in (out.means, out.covars, colors, self.opacities)
        )
        if self.background is not None:
            bm, bc, bsh, bo = self.background
            bcol = sh_colors(bsh, bm, cam.campos.to(bm))
            means, covars = torch.cat([means, bm]), torch.cat([covars, bc])
            colors, opacities = torch.cat([colors, bcol]), torch.cat([opacities, bo])
        img = render(
            means,
            covars,
            colors,
            opacities,
            cam.to(out.means.device),
            background=self.cfg.background,
            backend=self.cfg.backend,
            mode=self.cfg.mode,
        ).image
        return img.clamp(0, 1).mul_(255).round_().to(torch.uint8)  # ×255 and round in place on clamp's copy
