"""A recorded frame as the browser's splat buffer: which Gaussians, in which colours, packed as viser reads them.

viser's splat shader reads 32 bytes per Gaussian: the centre (3 float32), a reserved word, the covariance's upper
triangle (6 float16) and RGBA (4 uint8). The record already keeps covariances as float16 in units of the run's
`cov_unit` (`format`), so a frame is drawn in a local frame scaled by s = √cov_unit: centres / s, covariances as
stored, and the scene node scaled back by s. That keeps the float16 covariances of millimetre Gaussians in
float16's normal range, where they would underflow in metres.

Colour modes: `scene` (the Gaussians' own SH-DC colours, exposed interior as the video drew it), `fragment`
(each fragment in its own hue, the video's palette for `render.color_by = "fragment"`); `highlight` draws the
fracture band amber and its interfaces (band Gaussians facing another fragment) red over a faded object.
A preview keeps every k-th drawn Gaussian (at most `budget`), each widened to cover for the ones left out.
"""

from __future__ import annotations

import numpy as np

from . import format as fmt
from .store import Frame

COLOR_MODES = ("scene", "fragment")
BAND_RGB = np.array([1.0, 0.62, 0.10])
INTERFACE_RGB = np.array([0.86, 0.08, 0.08])


def fragment_rgb(fragment: np.ndarray, rgb: np.ndarray) -> np.ndarray:  # [N] int, [N,3] in [0,1] -> [N,3]
    """Each fragment in its own hue (golden-ratio spacing of the hue circle), shaded by the Gaussian's own
    brightness; a Gaussian of no fragment yet (−1) keeps its colour."""
    k = np.maximum(fragment, 0).astype(np.float64)
    hue = np.remainder(0.61803398875 * k + 0.08, 1.0)
    out = 0.5 + 0.45 * np.cos(2 * np.pi * (hue[:, None] + np.arange(3) / 3))
    out *= 0.55 + 0.45 * rgb.mean(1, keepdims=True)
    return np.where((fragment >= 0)[:, None], out, rgb)


def colors(frame: Frame, mode: str, highlight: bool) -> np.ndarray:  # -> [N,3] in [0,1]
    """The colour of every Gaussian of `frame` in colour `mode`, with the band and interfaces highlighted."""
    if mode not in COLOR_MODES:
        raise ValueError(f"colour mode must be one of {COLOR_MODES}, got {mode!r}")
    rgb = frame.rgb.astype(np.float64) / 255
    if mode == "fragment":
        rgb = fragment_rgb(frame.fragment.astype(np.int64), rgb)
    if highlight:
        rgb = 0.35 * rgb + 0.65 * 0.8  # the rest faded toward light grey
        band = (frame.flags & fmt.BAND) != 0
        rgb[band] = BAND_RGB
        rgb[(frame.flags & fmt.INTERFACE) != 0] = INTERFACE_RGB
    return rgb


def pack(centers: np.ndarray, cov16: np.ndarray, rgb: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """viser's splat buffer [M,8] uint32 from centres [M,3] float32, covariances [M,6] float16 (upper triangle),
    colours [M,3] in [0,1] and opacities [M] uint8."""
    m = len(centers)
    buf = np.zeros((m, 8), np.uint32)
    buf[:, :3] = np.ascontiguousarray(centers, "<f4").view("<u4")
    buf[:, 4:7] = np.ascontiguousarray(cov16, "<f2").view("<u4")
    rgba = np.empty((m, 4), np.uint8)
    rgba[:, :3] = np.rint(np.clip(rgb, 0, 1) * 255)
    rgba[:, 3] = alpha
    buf[:, 7:8] = rgba.view("<u4")
    return buf


def preview_stride(drawn: int, budget: int) -> int:
    """Keep every k-th drawn Gaussian so at most `budget` are sent (budget 0: all, k = 1)."""
    return 1 if budget <= 0 or drawn <= budget else -(-drawn // budget)


def frame_buffer(
    frame: Frame, opacity: np.ndarray, scale: float, mode: str = "scene", highlight: bool = False, budget: int = 0
) -> np.ndarray:
    """The splat buffer of a frame's drawn Gaussians in the local frame of node scale `scale` (= √cov_unit), in
    colour `mode`; with `budget` > 0, a preview of at most that many Gaussians (every k-th, each k^(1/3) wider)."""
    idx = np.nonzero(frame.flags & fmt.DRAWN)[0]
    k = preview_stride(len(idx), budget)
    idx = idx[::k]
    cov = frame.cov[idx]
    if k > 1:
        cov = (cov.astype(np.float32) * k ** (2 / 3)).clip(-fmt.F16_CLIP, fmt.F16_CLIP).astype(np.float16)
    rgb = colors(frame, mode, highlight)[idx]
    return pack(frame.means[idx] / np.float32(scale), cov, rgb, opacity[idx])


def background_buffer(static: dict, scale: float, faded: bool = False) -> np.ndarray:
    """The splat buffer of a capture's static background Gaussians (empty when the run has none); `faded`: toward
    light grey, as the object is when its band is highlighted."""
    if "background_means" not in static:
        return np.zeros((0, 8), np.uint32)
    rgb = static["background_rgb"].astype(np.float64) / 255
    if faded:
        rgb = 0.35 * rgb + 0.65 * 0.8
    centers = static["background_means"] / np.float32(scale)
    return pack(centers, static["background_cov"], rgb, static["background_opacity"])
