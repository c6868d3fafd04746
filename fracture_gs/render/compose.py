"""Comparison layouts for videos and figures: captions, side-by-side, grids, circular insets.

Images are numpy uint8 HxWx3 RGB (floats in [0, 1] and torch tensors are converted). Every
function returns an image with even height and width (H.264 yuv420p needs it).
"""

from __future__ import annotations

import functools
import math
from typing import Optional, Sequence

import cv2
import numpy as np

from ..errors import RenderError
from ..io.video import as_uint8_rgb, pad_even
from ..variants import VARIANT_SPECS

FONT = cv2.FONT_HERSHEY_SIMPLEX
BAR_BG = (40, 40, 40)
BAR_FG = (255, 255, 255)
CANVAS = (255, 255, 255)
INSET_COLOR = (255, 140, 0)
SHIFT = 4  # cv2 sub-pixel shift of the inset strokes: coordinates in 1/16 px


def _even(n: int) -> int:
    return n + (n % 2)


def _bar_height(width: int) -> int:
    return _even(max(16, min(36, width // 10)))


def _text_scale(text: str, max_w: int, max_h: int) -> tuple[float, int]:
    """Largest font scale (≤ what max_h allows) whose rendering fits max_w; and its thickness."""
    scale = max_h / 30.0
    (tw, _), _ = cv2.getTextSize(text, FONT, scale, 1)
    if tw > max_w > 0:
        scale *= max_w / tw
    return scale, 1


def _put_text_centered(
    img: np.ndarray, text: str, x0: int, y0: int, w: int, h: int, color, scale: Optional[float] = None
) -> None:
    fit, th = _text_scale(text, w - 6, h)
    scale = fit if scale is None else min(scale, fit)
    (tw, tht), base = cv2.getTextSize(text, FONT, scale, th)
    org = (x0 + max(0, (w - tw) // 2), y0 + (h + tht) // 2)
    cv2.putText(img, text, org, FONT, scale, color, th, cv2.LINE_AA)


@functools.lru_cache(maxsize=64)
def caption_bar(text: str, width: int, bar_height: int, scale: Optional[float] = None) -> np.ndarray:
    """The label bar of `caption` alone ([bar_height, width, 3] uint8, read only): drawn once per distinct
    (text, width, height, scale) and reused, e.g. the held last frame of a variant that stopped early."""
    bar = np.empty((bar_height, width, 3), np.uint8)
    bar[:] = BAR_BG
    _put_text_centered(bar, text, 0, 0, width, bar_height, BAR_FG, scale)
    bar.setflags(write=False)
    return bar


def caption(
    img, text: str, bar_height: Optional[int] = None, position: str = "top", scale: Optional[float] = None
) -> np.ndarray:
    """The image with a label bar (dark, centred white text) above (or below) it. The font scale
    is the largest that fits (capped by `scale`, so panels can share one size)."""
    if not isinstance(text, str):
        raise RenderError(f"caption: text must be a string, not {type(text).__name__}; pass e.g. str({text!r:.20}).")
    if position not in ("top", "bottom"):
        raise RenderError(f"caption: position = {position!r} is not 'top' or 'bottom'; pass one of those.")
    img = as_uint8_rgb(img)
    h, w = img.shape[:2]
    bar = caption_bar(text, w, bar_height or _bar_height(w), scale)
    out = np.concatenate([bar, img] if position == "top" else [img, bar], axis=0)
    return pad_even(out)


def caption_layout(widths: Sequence[int], captions: Sequence[str]) -> tuple[int, float]:
    """(bar height, font scale) shared by the captions of panels `widths` px wide, as `side_by_side` draws them."""
    bh = _bar_height(min(widths))
    return bh, min(_text_scale(c, w - 6, bh)[0] for w, c in zip(widths, captions))


def side_by_side(images: Sequence, captions: Optional[Sequence[str]] = None, gap: int = 4) -> np.ndarray:
    """Images in one row (shorter ones padded with white), each under its caption if given."""
    imgs = [as_uint8_rgb(i) for i in images]
    if not imgs:
        raise RenderError("side_by_side: images is empty; pass at least one image (an [H, W, 3] array).")
    if captions is not None:
        if len(captions) != len(imgs):
            raise RenderError(
                f"side_by_side: {len(imgs)} images but {len(captions)} captions; pass one caption per image, or "
                "captions=None."
            )
        bh, scale = caption_layout([i.shape[1] for i in imgs], captions)
        imgs = [caption(i, c, bh, scale=scale) for i, c in zip(imgs, captions)]
    h = max(i.shape[0] for i in imgs)
    out = np.empty((h, sum(i.shape[1] for i in imgs) + gap * (len(imgs) - 1), 3), np.uint8)
    canvas = np.asarray(CANVAS, np.uint8)  # filled where no image is: the gaps and below shorter images
    x = 0
    for k, i in enumerate(imgs):
        if k:
            out[:, x : x + gap] = canvas
            x += gap
        ih, iw = i.shape[:2]
        out[:ih, x : x + iw] = i
        out[ih:, x : x + iw] = canvas
        x += iw
    return pad_even(out)


def grid(
    rows_of_images: Sequence[Sequence],
    row_labels: Optional[Sequence[str]] = None,
    col_labels: Optional[Sequence[str]] = None,
    gap: int = 4,
) -> np.ndarray:
    """A table of images: column labels in a bar on top, row labels in a column on the left.
    Cells are padded (white) to the largest cell."""
    rows = [[as_uint8_rgb(i) for i in r] for r in rows_of_images]
    if not rows or not rows[0]:
        raise RenderError("grid: rows_of_images holds no image; pass rows of [H, W, 3] arrays, e.g. [[a, b]].")
    ncol = max(len(r) for r in rows)
    ch = max(i.shape[0] for r in rows for i in r)
    cw = max(i.shape[1] for r in rows for i in r)
    bh = _bar_height(cw)
    lw = 0
    if row_labels is not None:
        if len(row_labels) != len(rows):
            raise ValueError(f"grid: {len(rows)} rows but {len(row_labels)} row labels")
        scale = bh / 30.0
        lw = _even(max(cv2.getTextSize(t, FONT, scale, 1)[0][0] for t in row_labels) + 12)
    top = bh + gap if col_labels is not None else 0
    H = top + len(rows) * ch + (len(rows) - 1) * gap
    W = lw + ncol * cw + (ncol - 1) * gap
    out = np.empty((H, W, 3), np.uint8)
    out[:] = CANVAS
    if col_labels is not None:
        if len(col_labels) != ncol:
            raise ValueError(f"grid: {ncol} columns but {len(col_labels)} column labels")
        scale = min(_text_scale(t, cw - 6, bh)[0] for t in col_labels)
        for c, t in enumerate(col_labels):
            x0 = lw + c * (cw + gap)
            out[:bh, x0 : x0 + cw] = BAR_BG
            _put_text_centered(out, t, x0, 0, cw, bh, BAR_FG, scale)
    for r, row in enumerate(rows):
        y0 = top + r * (ch + gap)
        if row_labels is not None:
            _put_text_centered(out, row_labels[r], 0, y0 + (ch - bh) // 2, lw, bh, (0, 0, 0))
        for c, img in enumerate(row):
            x0 = lw + c * (cw + gap)
            out[y0 : y0 + img.shape[0], x0 : x0 + img.shape[1]] = img
    return pad_even(out)


def inset_placement(
    shape, center_xy, radius: float, zoom: float, margin: int = 4, gap: int = 4
) -> tuple[float, float, float]:
    """Centre (x, y) and radius R of the inset disc: the image corner that admits the largest
    R ≤ radius·zoom with the inset inside the image and ≥ `gap` px away from the source circle
    (centre_xy, radius). If no corner admits R ≥ 8 px, the corner farthest from the source is used
    with R = min(radius·zoom, a quarter of the short side) and may overlap it."""
    h, w = shape[:2]
    cx, cy = float(center_xy[0]), float(center_xy[1])
    r_max = min(radius * zoom, (min(h, w) - 2 * margin) / 2.0)
    corners = [(1, 1), (-1, 1), (1, -1), (-1, -1)]  # (sx, sy): +1 = left/top edge

    def centre(sx, sy, R):
        x = margin + R if sx > 0 else w - margin - R
        y = margin + R if sy > 0 else h - margin - R
        return x, y

    best = None
    for sx, sy in corners:
        R = r_max
        while R >= 8:
            x, y = centre(sx, sy, R)
            if math.hypot(x - cx, y - cy) >= R + radius + gap:
                break
            R -= 1.0
        if R >= 8 and (best is None or R > best[2] + 1e-9):
            best = (*centre(sx, sy, R), R)
    if best is None:
        R = min(radius * zoom, min(h, w) / 4.0)
        far = max(corners, key=lambda s: math.hypot(centre(*s, R)[0] - cx, centre(*s, R)[1] - cy))
        best = (*centre(*far, R), R)
    return best


def _outer_tangents(c1, r1, c2, r2):
    """End points of the two external common tangents of circles (c1, r1) and (c2, r2)."""
    dx, dy = c2[0] - c1[0], c2[1] - c1[1]
    d = math.hypot(dx, dy)
    if d <= abs(r2 - r1) + 1e-6:
        return []
    phi, th = math.atan2(dy, dx), math.acos((r1 - r2) / d)
    segs = []
    for a in (phi + th, phi - th):
        u = (math.cos(a), math.sin(a))
        segs.append(((c1[0] + r1 * u[0], c1[1] + r1 * u[1]), (c2[0] + r2 * u[0], c2[1] + r2 * u[1])))
    return segs


def _bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:  # [..]→[..,3] float
    """Bilinear sample at continuous pixel coordinates (pixel k's centre is at k + 0.5), edge clamp. Only the
    window the coordinates reach is converted (float32: an inset's values round to uint8 the same way to within
    one level of float64's)."""
    h, w = img.shape[:2]
    x = np.clip(x - 0.5, 0, w - 1)
    y = np.clip(y - 0.5, 0, h - 1)
    x0, y0 = np.floor(x).astype(np.int32), np.floor(y).astype(np.int32)
    if x0.size == 0:
        return np.zeros(x.shape + img.shape[2:], np.float32)
    ax, ay = int(x0.min()), int(y0.min())
    win = img[ay : int(y0.max()) + 2, ax : int(x0.max()) + 2].astype(np.float32)  # the sampled window only
    wh, ww = win.shape[:2]
    x0, y0 = x0 - ax, y0 - ay
    x1, y1 = np.minimum(x0 + 1, ww - 1), np.minimum(y0 + 1, wh - 1)
    fx = (x - ax - x0).astype(np.float32)[..., None]
    fy = (y - ay - y0).astype(np.float32)[..., None]
    flat = win.reshape(wh * ww, -1)  # gathers by row index: `take` is several times faster than 2-D indexing
    y0, y1 = y0 * ww, y1 * ww
    top = np.take(flat, y0 + x0, axis=0)
    top += (np.take(flat, y0 + x1, axis=0) - top) * fx
    bottom = np.take(flat, y1 + x0, axis=0)
    bottom += (np.take(flat, y1 + x1, axis=0) - bottom) * fx
    return top + (bottom - top) * fy


def disc_box(shape, inset_xy, inset_r: float) -> tuple[int, int, int, int, np.ndarray]:
    """(y0, y1, x0, x1, disc): the bounding box, clipped to the image, of the pixels whose centres (k + 0.5) lie
    within `inset_r` of `inset_xy`, and those pixels in it ([y1 − y0, x1 − x0] bool)."""
    h, w = shape[:2]
    x0 = min(w, max(0, math.floor(inset_xy[0] - inset_r - 1)))
    x1 = min(w, max(x0, math.ceil(inset_xy[0] + inset_r + 1)))
    y0 = min(h, max(0, math.floor(inset_xy[1] - inset_r - 1)))
    y1 = min(h, max(y0, math.ceil(inset_xy[1] + inset_r + 1)))
    ys, xs = np.mgrid[y0:y1, x0:x1] + 0.5
    return y0, y1, x0, x1, (xs - inset_xy[0]) ** 2 + (ys - inset_xy[1]) ** 2 <= inset_r**2


def magnify(img, center_xy, zoom: float, inset_xy, inset_r: float) -> tuple[np.ndarray, np.ndarray]:
    """Pixels of the inset disc and their values: inset pixel centre p maps to the source point
    center + (p − inset_centre)/zoom, sampled bilinearly. Returns (mask [H,W] bool, values [n,3])."""
    h, w = img.shape[:2]
    y0, y1, x0, x1, disc = disc_box(img.shape, inset_xy, inset_r)  # only the disc's box, row-major as before
    ys, xs = np.mgrid[y0:y1, x0:x1] + 0.5
    mask = np.zeros((h, w), bool)
    mask[y0:y1, x0:x1] = disc
    sx = center_xy[0] + (xs[disc] - inset_xy[0]) / zoom
    sy = center_xy[1] + (ys[disc] - inset_xy[1]) / zoom
    return mask, np.clip(np.rint(_bilinear(img, sx, sy)), 0, 255).astype(np.uint8)


def inset_geometry(
    shape, center_xy, radius: float, zoom: float, inset_center_xy=None, thickness: Optional[int] = None
) -> tuple[float, float, float, float, int]:
    """(ix, iy, R, z, t) of `add_inset`: the inset disc's centre and radius, the zoom it shows (R/radius) and
    the stroke thickness."""
    if inset_center_xy is None:
        ix, iy, R = inset_placement(shape, center_xy, radius, zoom)
    else:
        ix, iy = map(float, inset_center_xy)
        R = radius * zoom
    return ix, iy, R, R / max(radius, 1e-6), thickness or max(1, round(min(shape[:2]) / 200))


def _subpixel(p) -> tuple[int, int]:
    """A point in cv2's sub-pixel units (SHIFT bits; pixel k's centre is at k + 0.5)."""
    one = 1 << SHIFT
    return int(round(p[0] * one - 0.5 * one)), int(round(p[1] * one - 0.5 * one))


def draw_connectors(out: np.ndarray, center_xy, radius: float, inset_xy, R: float, color, t: int) -> None:
    """The two external tangents joining the source circle and the inset disc, drawn in place (anti-aliased)."""
    for a, b in _outer_tangents(center_xy, radius, inset_xy, R):
        cv2.line(out, _subpixel(a), _subpixel(b), color, t, cv2.LINE_AA, SHIFT)


def draw_rings(out: np.ndarray, center_xy, radius: float, inset_xy, R: float, color, t: int) -> None:
    """The source circle and the inset's outline, drawn in place (anti-aliased)."""
    for c, r in ((center_xy, radius), (inset_xy, R)):
        cv2.circle(out, _subpixel(c), int(round(r * (1 << SHIFT))), color, t, cv2.LINE_AA, SHIFT)


def add_inset(
    img, center_xy, radius: float, zoom: float, inset_center_xy=None, color=INSET_COLOR, thickness: Optional[int] = None
) -> np.ndarray:
    """Circular magnified inset of the disc (center_xy, radius).

    The inset (radius R = radius·zoom, reduced — and the zoom with it, R/radius — when a corner
    cannot hold it) goes in the image corner where it does not cover the source region
    (`inset_placement`), unless `inset_center_xy` is given. Draws the source circle, the inset
    outline and the two external tangents joining them as connectors (in that order: tangents, the
    magnified disc over them, the circles over both)."""
    src = as_uint8_rgb(img)
    out = src.copy()
    ix, iy, R, z, t = inset_geometry(src.shape, center_xy, radius, zoom, inset_center_xy, thickness)
    draw_connectors(out, center_xy, radius, (ix, iy), R, color, t)
    mask, vals = magnify(src, center_xy, z, (ix, iy), R)
    out[mask] = vals
    draw_rings(out, center_xy, radius, (ix, iy), R, color, t)
    return pad_even(out)


def interface_region(point, normal, extent: float, camera, n: int = 64) -> tuple[float, float, float]:
    """(cx, cy, r) in pixels: the projected centre of the latched interface disc (radius `extent`
    in the plane through `point` ⟂ `normal`) and the smallest radius about it covering the
    projected disc boundary (points behind the camera ignored)."""
    import torch

    p = torch.as_tensor(point, dtype=torch.float64).reshape(3)
    nrm = torch.as_tensor(normal, dtype=torch.float64).reshape(3)
    nrm = nrm / nrm.norm()
    a = torch.eye(3, dtype=torch.float64)[int(torch.argmin(nrm.abs()))]
    e1 = a - (a @ nrm) * nrm
    e1 = e1 / e1.norm()
    e2 = torch.linalg.cross(nrm, e1)
    th = torch.linspace(0, 2 * math.pi, n + 1, dtype=torch.float64)[:-1, None]
    ring = p + extent * (torch.cos(th) * e1 + torch.sin(th) * e2)
    cam = camera.to(dtype=torch.float64, device="cpu")
    (c,), (zc,) = cam.project(p[None])
    uv, z = cam.project(ring)
    uv = uv[z > 0]
    if zc <= 0 or uv.numel() == 0:
        raise ValueError("interface_region: the interface is behind the camera")
    r = float((uv - c).norm(dim=1).max())
    return float(c[0]), float(c[1]), max(r, 1.0)


def caption_text(variant: str, t: float, frame: int) -> str:
    """Panel caption, e.g. 'FractureFields  t=0.250 s  #25' (a name that is no variant is shown as it is)."""
    label = VARIANT_SPECS[variant].caption if variant in VARIANT_SPECS else variant
    return f"{label}  t={t:.3f} s  #{frame}"
