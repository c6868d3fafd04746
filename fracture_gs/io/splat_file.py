"""antimatter15 `.splat` files: 32 bytes a Gaussian, no header (the web viewer's compact format).

Row layout, little-endian:

    float32 x, y, z                mean
    float32 sx, sy, sz             standard deviations (linear, not log)
    uint8   r, g, b, a             colour = 0.5 + SH_C0 · f_dc and opacity, each × 255
    uint8   qw, qx, qy, qz         unit quaternion, each component q · 128 + 128

What the format loses: SH beyond the DC term (view-dependent colour), colour outside [0, 1] (clipped),
and precision: 8 bits of colour and opacity, about 1/128 per quaternion component. Means and scales
are float32 and survive exactly. The reader returns arrays in the package's activated convention
(linear scales, opacity in [0, 1], wxyz quaternions normalised, SH DC); rows it cannot use are the
caller's to drop (`formats.read_gaussians`).
"""

from __future__ import annotations

import numpy as np

from ..sh import SH_C0

ROW_BYTES = 32
ROW = np.dtype(
    [("mean", "<f4", (3,)), ("scale", "<f4", (3,)), ("rgba", "u1", (4,)), ("rot", "u1", (4,))]
)  # 32 bytes, no padding


def decode(raw: bytes | np.ndarray) -> dict:
    """The rows of a `.splat` byte string as float arrays: means [N, 3], scales [N, 3] (linear),
    quats [N, 4] (wxyz; a zero quaternion stays zero), opacities [N], sh [N, 1, 3] (DC only).
    The length must be a multiple of 32 (the caller checks and says so)."""
    rows = np.frombuffer(raw, dtype=ROW)
    rgba = rows["rgba"].astype(np.float64) / 255.0  # [N, 4]
    q = (rows["rot"].astype(np.float64) - 128.0) / 128.0  # [N, 4]
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        quats = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), 0.0)
    return {
        "means": rows["mean"].astype(np.float32),
        "scales": rows["scale"].astype(np.float32),
        "quats": quats.astype(np.float32),
        "opacities": rgba[:, 3].astype(np.float32),
        "sh": ((rgba[:, None, :3] - 0.5) / SH_C0).astype(np.float32),
    }


def encode(means, scales, quats, opacities, sh_dc) -> bytes:
    """`.splat` bytes of N Gaussians: means [N, 3], scales [N, 3] linear, quats [N, 4] wxyz (any norm,
    non-zero), opacities [N] in [0, 1], sh_dc [N, 3]. Colour, opacity and quaternion are rounded to
    the nearest byte (antimatter15's converter truncates; rounding halves the error)."""
    n = len(means)
    rows = np.zeros(n, dtype=ROW)
    rows["mean"] = np.asarray(means, np.float32)
    rows["scale"] = np.asarray(scales, np.float32)
    rgb = 0.5 + SH_C0 * np.asarray(sh_dc, np.float64)  # [N, 3]
    rgba = np.concatenate([rgb, np.asarray(opacities, np.float64)[:, None]], axis=1)
    rows["rgba"] = np.clip(np.rint(rgba * 255.0), 0, 255).astype(np.uint8)
    q = np.asarray(quats, np.float64)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    rows["rot"] = np.clip(np.rint(q * 128.0 + 128.0), 0, 255).astype(np.uint8)
    return rows.tobytes()


def plausible_rows(raw: bytes) -> float:
    """The fraction of `.splat` rows that look like Gaussians: finite means within 1e7, scales in
    [1e-12, 1e6] and a quaternion that is not zero. `.splat` has no magic number, so this is how a
    file is recognised; a real capture scores near 1, text and random bytes far lower (their float
    signs, exponents and the scales' positivity rarely all agree)."""
    n = len(raw) // ROW_BYTES
    if n == 0:
        return 0.0
    pick = np.unique(np.linspace(0, n - 1, min(n, 4096)).astype(np.int64))
    rows = np.frombuffer(raw, dtype=ROW, count=n)[pick]
    with np.errstate(invalid="ignore", over="ignore"):
        mean = rows["mean"].astype(np.float64)
        scale = rows["scale"].astype(np.float64)
        ok = np.isfinite(mean).all(1) & (np.abs(mean) < 1e7).all(1)
        ok &= np.isfinite(scale).all(1) & (scale >= 1e-12).all(1) & (scale <= 1e6).all(1)
        ok &= (rows["rot"] != 128).any(1)
    return float(ok.mean())
