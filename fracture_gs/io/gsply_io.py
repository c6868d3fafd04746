"""Quantised splat files through `gsply`: PlayCanvas/SuperSplat compressed PLY and Niantic SPZ.

gsply (imported here, inside the functions, never at package import) decodes both into log-scales,
logit-opacities, wxyz quaternions and SH DC + rest; this module turns them into the package's
activated arrays (linear scales, opacity in [0, 1], unit quaternions, SH [N, K, 3] DC first) and back.

- **Compressed PLY** (`*.compressed.ply`): chunks of 256 Gaussians, each with float min/max bounds;
  per Gaussian 16 bytes: position and log-scale as 11-10-11-bit fractions of the chunk's bounds,
  colour 8 bits a channel within the chunk's colour bounds, opacity 8 bits, the quaternion as its
  three smallest components at 10 bits. Optional SH rest at 8 bits over [-4, 4]. A chunk's bounds
  span its 256 Gaussians, so the writer first puts the Gaussians in Morton (Z-curve) order, as
  SuperSplat does: neighbours share a chunk and the 11-bit steps stay small. Rows come back reordered.
- **SPZ** (`*.spz`, versions 2-4; v2/v3 gzip, v4 "NGSP" with zstd streams): positions 24-bit fixed
  point (the header's fractional bits), log-scales in 1/16 steps over [-10, 6], opacity 8 bits, DC
  colour 8 bits over ±3.3, quaternions 8 bits a component (v2) or smallest-three at 9 bits (v3+), SH
  rest 8 bits over [-1, 1]. SPZ stores RUB axes (x right, y up, z back); a 3DGS PLY is RDF (y down,
  z forward). The two differ by a half turn about x, so reading and writing both flip y and z, the
  quaternion's y and z and the SH coefficients odd in y·z (`flip_yz`): the rest of the package sees
  PLY conventions. The writer picks the most fractional bits (up to SPZ's usual 12) that still hold
  the largest coordinate in 24 bits.
"""

from __future__ import annotations

import numpy as np

from ..errors import PlyError
from .ply import activate_opacity, activate_scale, inverse_opacity, inverse_scale

# SH coefficient signs under (x, y, z) -> (x, -y, -z): a basis function odd in y·z changes sign.
# Real SH order as in 3DGS: degree 1 (y, z, x); degree 2 (xy, yz, 3z²-1, xz, x²-y²); degree 3
# (y(3x²-y²), xyz, y(5z²-1), z(5z²-3), x(5z²-1), z(x²-y²), x(x²-3y²)).
_FLIP_SH = np.array([1, -1, -1, 1, -1, 1, 1, -1, 1, -1, 1, -1, -1, 1, -1, 1], np.float32)  # [16]
SPZ_FRACTIONAL_BITS = 12
_POS_LIMIT = (1 << 23) - 1  # the largest 24-bit signed fixed-point value


def flip_yz(means, quats, sh):  # [N, 3], [N, 4] wxyz, [N, K, 3] -> the same shapes
    """The Gaussians turned half a turn about x (RUB <-> RDF; its own inverse): y, z -> -y, -z;
    q -> (w, x, -y, -z) (R -> D R D with D = diag(1, -1, -1)); SH odd in y·z change sign."""
    means = means * np.array([1, -1, -1], np.float32)
    quats = quats * np.array([1, 1, -1, -1], np.float32)
    sh = sh * _FLIP_SH[: sh.shape[1], None]
    return means, quats, sh


def morton_order(means: np.ndarray) -> np.ndarray:  # [N, 3] -> [N] int64 permutation
    """The Gaussians sorted along a Z-order curve of their bounding box (10 bits an axis)."""
    m = np.asarray(means, np.float64)
    lo, hi = m.min(0), m.max(0)
    cell = np.clip(((m - lo) / np.maximum(hi - lo, 1e-30) * 1023.0).astype(np.int64), 0, 1023)
    code = np.zeros(len(m), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cell[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(code, kind="stable")


def _activated(data) -> dict:
    """gsply's GSData (log-scales, logit-opacities, sh0 + shN) -> the package's activated arrays."""
    n = len(data.means)
    shn = data.shN if data.shN is not None else np.zeros((n, 0, 3), np.float32)
    sh = np.concatenate([np.asarray(data.sh0, np.float32)[:, None, :], np.asarray(shn, np.float32)], 1)
    q = np.asarray(data.quats, np.float64)
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        quats = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), 0.0)
    return {
        "means": np.asarray(data.means, np.float32),
        "scales": activate_scale(np.asarray(data.scales)),
        "quats": quats.astype(np.float32),
        "opacities": activate_opacity(np.asarray(data.opacities).reshape(-1)),
        "sh": sh,
    }


def _ply_space(a: dict) -> tuple:
    """Activated arrays -> (means, log-scales, quats, logit-opacities, sh0 [N, 3], shN [N, K-1, 3] or None)."""
    logit = inverse_opacity(np.clip(a["opacities"], 0.0, 1.0))
    sh = np.asarray(a["sh"], np.float32)
    shn = np.ascontiguousarray(sh[:, 1:]) if sh.shape[1] > 1 else None
    return (
        np.ascontiguousarray(a["means"], np.float32),
        inverse_scale(a["scales"]),
        np.ascontiguousarray(a["quats"], np.float32),
        logit,
        np.ascontiguousarray(sh[:, 0]),
        shn,
    )


def _failed(path, what: str, err: Exception) -> PlyError:
    reason = " ".join(str(err).split())[:160] or type(err).__name__
    return PlyError(f"{path}: is {what} that could not be decoded ({reason}); export it again from its source.")


def read_compressed_ply(path) -> dict:
    """A PlayCanvas compressed PLY as activated arrays (means, scales, quats, opacities, sh)."""
    import gsply

    try:
        data = gsply.plyread(str(path))
    except Exception as err:  # noqa: BLE001 - gsply and numpy raise many types; the user gets one sentence
        raise _failed(path, "a compressed PLY", err) from None
    return _activated(data)


def read_spz(path) -> dict:
    """A Niantic SPZ file as activated arrays in PLY axes (RDF)."""
    import gsply

    try:
        data = gsply.read_spz(str(path))
    except Exception as err:  # noqa: BLE001
        raise _failed(path, "an SPZ file", err) from None
    a = _activated(data)
    a["means"], a["quats"], a["sh"] = flip_yz(a["means"], a["quats"], a["sh"])
    return a


def write_compressed_ply(a: dict, path) -> None:
    """Activated arrays -> a compressed PLY at `path` (Gaussians in Morton order)."""
    import gsply

    order = morton_order(a["means"])
    means, log_s, quats, logit, sh0, shn = (x[order] if x is not None else None for x in _ply_space(a))
    raw = gsply.compress_to_bytes(means, log_s, quats, logit, sh0, shn)
    with open(path, "wb") as fh:
        fh.write(raw)


def spz_fractional_bits(means: np.ndarray) -> int:
    """The most fractional bits, at most 12, whose 24-bit fixed point still holds every coordinate."""
    biggest = float(np.abs(means).max()) if len(means) else 0.0
    bits = SPZ_FRACTIONAL_BITS
    while bits > 0 and biggest * (1 << bits) > _POS_LIMIT:
        bits -= 1
    return bits


def write_spz(a: dict, path) -> None:
    """Activated arrays (PLY axes) -> an SPZ v3 file (gzip; RUB axes) at `path`."""
    import gsply

    means, quats, sh = flip_yz(a["means"], a["quats"], a["sh"])
    bits = spz_fractional_bits(means)
    if bits == 0 or float(np.abs(means).max()) > _POS_LIMIT:
        raise PlyError(
            f"{path}: a coordinate of {float(np.abs(means).max()):.4g} does not fit SPZ's 24-bit positions "
            "(at most ±4.2e6 with whole-unit steps); write ply or compressed-ply instead."
        )
    m, log_s, q, logit, sh0, shn = _ply_space({**a, "means": means, "quats": quats, "sh": sh})
    data = gsply.GSData(
        means=m,
        scales=log_s,
        quats=q,
        opacities=logit,
        sh0=sh0,
        shN=shn if shn is not None else np.zeros((len(m), 0, 3), np.float32),
        _format=gsply.create_ply_format(int(round(sh.shape[1] ** 0.5)) - 1),
    )
    gsply.write_spz(str(path), data, version=3, fractional_bits=bits)
