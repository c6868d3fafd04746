"""The comparison row (panels side by side, captions, circular insets) composed as torch ops on the panels' device,
with one copy of the finished frame to the host.

`compose_row(images, captions, insets)` gives the pixels of `compose.side_by_side` over `compose.add_inset` panels,
byte for byte (tests/test_compose_torch.py), split by what each side does cheaply and exactly:

- on the device (a GPU, or the CPU as torch tensors): the canvas, each panel copied into place and its inset disc
  magnified, with the numpy path's bilinear formula in the same dtypes and order (float64 coordinates, float32
  values, separate add and multiply, rounding half to even), so every value rounds the same way;
- then one copy of the whole frame to the host;
- on the host, into that copy: the anti-aliased strokes (the inset's connectors and circles, drawn by the same
  `compose.draw_connectors` / `draw_rings` calls as `add_inset`, with the disc's pixels kept aside and put back
  between them, which reproduces "connectors, then the disc over them, then the circles"), the caption bars (drawn
  once per distinct text, `compose.caption_bar`, and pasted) and the edge padding to even sizes, in the order the
  numpy path pads. OpenCV's anti-aliasing (fixed-point blending, thick lines as filled polygons) has no exact torch
  twin; the strokes and the text cover a few hundred pixels of a frame and cost tens of microseconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np
import torch

from ..io.video import as_uint8_rgb
from . import compose


@dataclass(frozen=True)
class Inset:
    """A circular magnified inset of one panel: `compose.add_inset(img, center, radius, zoom)` with its automatic
    placement, colour and stroke thickness."""

    center: tuple[float, float]
    """Centre of the magnified region, pixels (x, y)."""
    radius: float
    """Radius of the magnified region, pixels."""
    zoom: float
    """Magnification (the inset's radius is radius·zoom, reduced when no corner holds it)."""


def _even(n: int) -> int:
    return n + n % 2


def _as_tensor(img, device: torch.device) -> torch.Tensor:  # -> [H, W, 3] uint8 on `device`
    """A uint8 [H, W, 3] tensor on `device`: a tensor moved there (no copy if it is), a numpy image shared."""
    if torch.is_tensor(img) and img.dtype == torch.uint8 and img.dim() == 3 and img.shape[2] == 3:
        return img.to(device)
    if isinstance(img, np.ndarray) and img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3:
        return torch.from_numpy(np.ascontiguousarray(img)).to(device)
    return torch.from_numpy(as_uint8_rgb(img)).to(device)  # float, grey or RGBA images as the numpy path reads them


def _fill(region: torch.Tensor, rgb) -> None:
    """Set every pixel of `region` ([..., 3]) to the colour `rgb`, without a host-to-device copy."""
    if rgb[0] == rgb[1] == rgb[2]:
        region.fill_(rgb[0])
    else:
        for c in range(3):
            region[..., c].fill_(rgb[c])


def _axis(lo: int, hi: int, inset_c: float, center_c: float, zoom: float, size: int, device):
    """Along one image axis, for the pixel centres lo + 0.5 … hi − 0.5 of the inset's box: the two source pixels
    each samples and its weight on the second, as `compose._bilinear` computes them (float64 until the weight,
    which is float32). Returns (i0, i1 [n] int64, f [n] float32)."""
    c = torch.arange(lo, hi, dtype=torch.float64, device=device) + 0.5
    s = center_c + (c - inset_c) / zoom  # the source coordinate of each inset pixel centre
    s = (s - 0.5).clamp(0, size - 1)
    s0 = torch.floor(s)
    i0 = s0.to(torch.int64)
    return i0, (i0 + 1).clamp(max=size - 1), (s - s0).to(torch.float32)


def _magnify_into(dst: torch.Tensor, src: torch.Tensor, center, zoom: float, inset_xy, R: float, box) -> None:
    """Write the inset disc of `src` ([h, w, 3] uint8) into `dst` (the same size): the pixels of `box`'s disc take
    the bilinear sample of the point center + (p − inset_xy)/zoom, as `compose.magnify` gives them."""
    h, w = src.shape[:2]
    y0, y1, x0, x1, disc = box
    if y1 <= y0 or x1 <= x0 or not disc.any():
        return
    xa, xb, fx = _axis(x0, x1, inset_xy[0], center[0], zoom, w, src.device)  # [bw]
    ya, yb, fy = _axis(y0, y1, inset_xy[1], center[1], zoom, h, src.device)  # [bh]
    fx, fy = fx[None, :, None], fy[:, None, None]
    rows_a, rows_b = src.index_select(0, ya), src.index_select(0, yb)  # [bh, w, 3]
    # a + (b − a)·f with its operations in its order, in place on the float32 copies: (b − a)·f into b, then a + it
    top = rows_a.index_select(1, xa).to(torch.float32)  # [bh, bw, 3]
    top.add_(rows_a.index_select(1, xb).to(torch.float32).sub_(top).mul_(fx))
    bottom = rows_b.index_select(1, xa).to(torch.float32)
    bottom.add_(rows_b.index_select(1, xb).to(torch.float32).sub_(bottom).mul_(fx))
    vals = top.add_(bottom.sub_(top).mul_(fy)).round_().clamp_(0, 255).to(torch.uint8)
    inside = torch.from_numpy(disc).to(src.device)[..., None]  # [bh, bw, 1]
    region = dst[y0:y1, x0:x1]
    region.copy_(torch.where(inside, vals, region))


def _pad_edges(view: np.ndarray, h: int, w: int) -> None:
    """Fill the padding of an image whose first h × w pixels are set and whose view is even-sized: the last column,
    then the last row, repeated (as `io.video.pad_even`, corner included)."""
    if w % 2:
        view[:h, w] = view[:h, w - 1]
    if h % 2:
        view[h, : _even(w)] = view[h - 1, : _even(w)]


def _host_insets(panel: np.ndarray, inset: Inset, geometry, box) -> None:
    """The inset's strokes drawn into `panel` (the host copy, the disc already magnified in it): the connectors, then
    the disc's pixels put back over them, then the circles, as `compose.add_inset` draws them."""
    ix, iy, R, _, t = geometry
    y0, y1, x0, x1, disc = box
    box_px = panel[y0:y1, x0:x1]
    kept = box_px.copy()  # [bh, bw, 3]
    compose.draw_connectors(panel, inset.center, inset.radius, (ix, iy), R, compose.INSET_COLOR, t)
    np.copyto(box_px, kept, where=disc[..., None])
    compose.draw_rings(panel, inset.center, inset.radius, (ix, iy), R, compose.INSET_COLOR, t)


def compose_row(
    images: Sequence,
    captions: Optional[Sequence[str]] = None,
    insets: Optional[Sequence[Optional[Inset]]] = None,
    gap: int = 4,
    device=None,
) -> np.ndarray:  # -> [H, W, 3] uint8, even sides
    """`compose.side_by_side([compose.add_inset(img, *inset) ...], captions, gap)` (a panel whose inset is None is
    used as it is), composed on `device` (default: the first tensor panel's device, else the CPU) and returned as
    the host image. `images`: uint8 [H, W, 3] torch tensors (any device) or numpy arrays; other images (float,
    grey, RGBA) are read as the numpy path reads them."""
    if not len(images):
        raise ValueError("compose_row: no images")
    if captions is not None and len(captions) != len(images):
        raise ValueError(f"compose_row: {len(images)} images but {len(captions)} captions")
    insets = list(insets) if insets is not None else [None] * len(images)
    if len(insets) != len(images):
        raise ValueError(f"compose_row: {len(images)} images but {len(insets)} insets")
    if device is None:
        device = next((i.device for i in images if torch.is_tensor(i)), torch.device("cpu"))
    panels = [_as_tensor(i, torch.device(device)) for i in images]

    # layout, on the host: each panel's size after its inset (padded to even) and caption bar
    sizes = [tuple(p.shape[:2]) for p in panels]
    geometry = [
        compose.inset_geometry((h, w), s.center, s.radius, s.zoom) if s is not None else None
        for (h, w), s in zip(sizes, insets)
    ]
    boxes = [compose.disc_box((h, w), g[:2], g[2]) if g is not None else None for (h, w), g in zip(sizes, geometry)]
    inner = [(_even(h), _even(w)) if g is not None else (h, w) for (h, w), g in zip(sizes, geometry)]
    bh, scale = compose.caption_layout([w for _, w in inner], captions) if captions is not None else (0, None)
    outer = [(bh + _even(h), _even(w)) if captions is not None else (h, w) for h, w in inner]
    H, W = max(h for h, _ in outer), sum(w for _, w in outer) + gap * (len(outer) - 1)
    xs = np.cumsum([0] + [w + gap for _, w in outer[:-1]]).tolist()

    # on the device: the white canvas, the panels, the magnified discs
    canvas = torch.empty((_even(H), _even(W), 3), dtype=torch.uint8, device=panels[0].device)
    _fill(canvas, compose.CANVAS)
    for p, (h, w), x, g, s, box in zip(panels, sizes, xs, geometry, insets, boxes):
        dst = canvas[bh : bh + h, x : x + w]
        dst.copy_(p)
        if g is not None:
            _magnify_into(dst, p, s.center, g[3], g[:2], g[2], box)
    out = canvas.cpu().numpy()  # the one copy to the host

    # on the host: strokes, caption bars, edge padding (inset, then caption, then the row: the numpy path's order)
    for k, ((h, w), (ih, iw), x, g, s) in enumerate(zip(sizes, inner, xs, geometry, insets)):
        if g is not None:
            _host_insets(out[bh : bh + h, x : x + w], s, g, boxes[k])
            _pad_edges(out[bh : bh + ih, x : x + iw], h, w)
        if captions is not None:
            out[:bh, x : x + iw] = compose.caption_bar(captions[k], iw, bh, scale)
            _pad_edges(out[: bh + _even(ih), x : x + _even(iw)], bh + ih, iw)
    _pad_edges(out, H, W)
    return out
