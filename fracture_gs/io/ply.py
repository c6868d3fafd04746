"""3D Gaussian Splatting PLY files: `load_ply` and `save_ply`.

Layout (INRIA trainer, gsplat, nerfstudio), one `vertex` element, properties read BY NAME:

    x y z                       means
    nx ny nz                    optional, unused (kept in `extra` when present)
    f_dc_0..2                   SH DC term per channel (R, G, B)
    f_rest_0..3(K-1)-1          higher SH coefficients, channel-major: all R, then all G, then all B
    opacity                     logit of the opacity
    scale_0..2                  log of the standard deviations
    rot_0..3                    quaternion wxyz, not necessarily normalized

`GaussianSet` holds activated values (exp, sigmoid, normalized quaternions). The activation is
done in float64 and stored as float32; because exp/sigmoid lose information in float32, the set
returned by `load_ply` also remembers the raw file values, and `save_ply` writes a raw value back
wherever the activated value is still the one it came from (so `save_ply(load_ply(f))` reproduces
every property bit for bit) and the float64 inverse elsewhere. Other vertex properties travel in
`gs.extra`; `interior` and `labels` are written as `fgs_interior` (uint8) and `fgs_label` (int32).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import torch
from plyfile import PlyData, PlyElement

from ..errors import ArgumentError, OutputError, PlyError
from .detect import SUFFIX, as_path, detect_format, named_format
from .devices import as_device  # callers import it from here too (io.ply.as_device)
from .gaussian_set import SIGMA_RANGE, GaussianSet

INTERIOR_PROP = "fgs_interior"
LABEL_PROP = "fgs_label"
NORMAL_PROPS = ("nx", "ny", "nz")
SH_REST_COUNTS = {0: 0, 9: 1, 24: 2, 45: 3}  # number of f_rest_* -> SH degree
_LOGIT_CLAMP = 80.0  # |logit| written for opacities 0 or 1 (sigmoid(80) == 1 in float32)


@dataclass
class _RawCache:
    """Raw file values of the activated fields, so that `save_ply` can reproduce them exactly."""

    scale: np.ndarray  # [N, 3] float32 log-scales as read
    opacity: np.ndarray  # [N] float32 logits as read
    rot: np.ndarray  # [N, 4] float32 quaternions as read
    order: list = field(default_factory=list)  # property names in file order
    had_normals: bool = False
    had_interior: bool = False
    had_label: bool = False


# ----------------------------------------------------------------------------- activations


def activate_scale(raw: np.ndarray) -> np.ndarray:
    """exp(log-scale) in float64, stored as float32."""
    with np.errstate(over="ignore"):
        return np.exp(raw.astype(np.float64)).astype(np.float32)


def activate_opacity(raw: np.ndarray) -> np.ndarray:
    """sigmoid(logit) in float64, stored as float32."""
    with np.errstate(over="ignore"):
        return (1.0 / (1.0 + np.exp(-raw.astype(np.float64)))).astype(np.float32)


def _activate_rot(raw: np.ndarray) -> np.ndarray:  # [N, 4]
    """q / |q| in float64, stored as float32 (zero quaternions are rejected before this)."""
    q = raw.astype(np.float64)
    return (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)


def inverse_scale(s: np.ndarray) -> np.ndarray:
    return np.log(s.astype(np.float64)).astype(np.float32)


def inverse_opacity(p: np.ndarray) -> np.ndarray:
    p = p.astype(np.float64)
    with np.errstate(divide="ignore"):
        logit = np.log(p) - np.log1p(-p)
    return np.clip(logit, -_LOGIT_CLAMP, _LOGIT_CLAMP).astype(np.float32)


# ----------------------------------------------------------------------------- arguments


def as_gaussians(where: str, gs) -> GaussianSet:
    """The GaussianSet argument of a writer, or an ArgumentError naming it."""
    if not isinstance(gs, GaussianSet):
        raise ArgumentError(
            f"{where}: gs must be a GaussianSet, got {type(gs).__name__}; build one with "
            "fracture_gs.io.GaussianSet(means=..., quats=..., scales=..., opacities=..., sh=...)."
        )
    return gs


def write_failed(path, err: OSError) -> OutputError:
    """The one sentence for a splat file that cannot be written (a missing folder, a folder in the way, no
    permission)."""
    why = err.strerror or type(err).__name__
    return OutputError(f"{path}: cannot write the file ({why}); check that its folder exists and is writable.")


# ----------------------------------------------------------------------------- reading


def _fail(path, msg: str) -> PlyError:
    return PlyError(f"{path}: {msg}" + ("" if msg.endswith(".") else "."))  # one sentence, ended


def _read_vertex(path) -> tuple[np.ndarray, list]:
    """The structured vertex array of a PLY file and its property names (errors wrapped)."""
    if os.path.isdir(path):
        raise _fail(path, "is a folder, not a file; pass the .ply file inside it")
    if not os.path.isfile(path):
        raise _fail(path, "no such file; check the path to the 3DGS .ply")
    try:
        ply = PlyData.read(str(path))
    except Exception as err:  # plyfile raises many types; the user gets one sentence
        reason = " ".join(str(err).split())[:160] or type(err).__name__
        raise _fail(
            path, f"is not a readable PLY file ({reason}); export the scene again as a binary 3DGS .ply"
        ) from None
    names = [el.name for el in ply.elements]
    if "vertex" not in names:
        raise _fail(
            path,
            f"has no 'vertex' element (elements: {names or 'none'}); a 3DGS .ply "
            "stores one Gaussian per vertex, so export the Gaussians, not a mesh",
        )
    data = ply["vertex"].data
    if len(data) == 0:
        raise _fail(path, "element 'vertex' is empty; the scene has no Gaussians to load")
    return data, list(data.dtype.names)


def _column(path, data, name: str) -> np.ndarray:  # [N]
    """One finite numeric property as float32 (error names the property otherwise)."""
    col = np.asarray(data[name])
    if col.dtype == object or col.dtype.kind not in "fiub":
        raise _fail(path, f"property '{name}' is not a numeric scalar; write it as float32")
    col = col.astype(np.float32)
    bad = ~np.isfinite(col)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        raise _fail(
            path,
            f"property '{name}' has {int(bad.sum())} NaN/inf values (first at vertex "
            f"{first}, value {col[first]}); remove or repair those Gaussians before "
            "loading",
        )
    return col


def _require(path, names: list, wanted: list) -> None:
    missing = [w for w in wanted if w not in names]
    if missing:
        raise _fail(
            path,
            f"missing required property '{missing[0]}'"
            + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else "")
            + "; a 3DGS .ply needs x y z, f_dc_0..2, opacity, scale_0..2 and "
            "rot_0..3, so export it from a Gaussian splatting trainer",
        )


def _rest_names(path, names: list) -> list:
    """f_rest_0..M-1 in index order, checking M is 0, 9, 24 or 45 and the indices are contiguous."""
    rest = [n for n in names if n.startswith("f_rest_")]
    idx = sorted(int(n[7:]) for n in rest if n[7:].isdigit())
    if len(idx) != len(rest) or idx != list(range(len(rest))):
        gap = next((f"f_rest_{i}" for i in range(len(rest)) if i not in idx), rest[-1])
        raise _fail(
            path,
            f"property '{gap}' is missing: the {len(rest)} f_rest_* properties must "
            f"be numbered 0..{len(rest) - 1} without gaps; re-export the SH coefficients",
        )
    if len(rest) not in SH_REST_COUNTS:
        raise _fail(
            path,
            f"property 'f_rest_*' has {len(rest)} coefficients, but SH degree 0-3 "
            "needs 0, 9, 24 or 45; re-export with a supported SH degree",
        )
    return [f"f_rest_{i}" for i in range(len(rest))]


def _check_scales(path, raw: np.ndarray, act: np.ndarray) -> None:  # [N, 3] each
    bad = ~_sigma_ok(act)
    if bad.any():
        v, k = (int(i) for i in np.argwhere(bad)[0])
        raise _fail(
            path,
            f"property 'scale_{k}' gives {int(bad.sum())} standard deviations outside [1e-18, 1e18] after exp, "
            f"whose covariance would be singular or infinite (first at vertex {v}, log-scale {raw[v, k]}); clamp "
            "log-scales to a finite range such as [-30, 10] before saving",
        )


def _check_rots(path, raw: np.ndarray) -> None:  # [N, 4]
    norm = np.linalg.norm(raw.astype(np.float64), axis=1)
    bad = ~(norm > 0)
    if bad.any():
        raise _fail(
            path,
            f"properties 'rot_0..rot_3' are a zero quaternion at {int(bad.sum())} "
            f"vertices (first at vertex {int(np.flatnonzero(bad)[0])}); write a unit "
            "quaternion such as (1, 0, 0, 0) for those Gaussians",
        )


def _native(col: np.ndarray) -> np.ndarray:
    """An aligned, contiguous copy in the machine's byte order (big-endian files, packed records)."""
    dtype = col.dtype.newbyteorder("=")
    if dtype.kind == "u" and dtype.itemsize > 1:  # torch has no arithmetic on uint16/32/64
        dtype = np.dtype(np.int64)
    return np.array(col, dtype=dtype, order="C", copy=True)


def _extra_tensor(path, data, name: str, device) -> torch.Tensor | None:
    col = np.asarray(data[name])
    if col.dtype == object:  # list property: not representable as an [N] tensor
        return None
    return torch.from_numpy(_native(col)).to(device)


def _sigma_ok(act: np.ndarray) -> np.ndarray:  # [N, 3] -> [N, 3] bool
    a = act.astype(np.float64)
    return np.isfinite(a) & (a >= SIGMA_RANGE[0]) & (a <= SIGMA_RANGE[1])


def _label_ok(data) -> np.ndarray:  # [N] bool
    """`fgs_label` values that are material labels: finite integers in [0, 2^31 − 1] (int32)."""
    raw = np.asarray(data[LABEL_PROP]).astype(np.float64)
    with np.errstate(invalid="ignore"):
        return np.isfinite(raw) & (raw == np.round(raw)) & (raw >= 0) & (raw <= 2**31 - 1)


def _interior_ok(data) -> np.ndarray:  # [N] bool
    """`fgs_interior` values that are flags: 0 or 1."""
    raw = np.asarray(data[INTERIOR_PROP]).astype(np.float64)
    return (raw == 0) | (raw == 1)


def _checked(path, data, name: str, ok: np.ndarray, fix: str) -> np.ndarray:  # [N] float64
    """The column as float64, or one sentence naming the property, the first bad vertex and the fix."""
    raw = np.asarray(data[name]).astype(np.float64)
    if not ok.all():
        first = int(np.flatnonzero(~ok)[0])
        raise _fail(
            path,
            f"property '{name}' has {int((~ok).sum())} {fix[0]} "
            f"(first at vertex {first}, value {raw[first]}); {fix[1]}",
        )
    return raw


def _labels(path, data) -> np.ndarray:  # [N] int32
    fix = ("values that are not material labels", "write non-negative integers below 2^31 (int32)")
    return _checked(path, data, LABEL_PROP, _label_ok(data), fix).astype(np.int32)


def _interior(path, data) -> np.ndarray:  # [N] bool
    fix = ("values other than 0 and 1", "write 1 for interior fill particles and 0 for surface Gaussians (uint8)")
    return _checked(path, data, INTERIOR_PROP, _interior_ok(data), fix) != 0


def _usable_rows(data, names: list) -> np.ndarray:  # [N] bool
    """Vertices that `load_ply` would accept on their own: float properties finite as float32, σ = exp(log-scale)
    within SIGMA_RANGE, quaternion ≠ 0, fgs_label a non-negative int32 integer, fgs_interior 0 or 1."""
    ok = np.ones(len(data), dtype=bool)
    with np.errstate(over="ignore", invalid="ignore"):
        for name in names:
            col = np.asarray(data[name])
            if col.dtype != object and col.dtype.kind == "f":
                ok &= np.isfinite(col.astype(np.float32))
        for i in range(3):
            ok &= _sigma_ok(activate_scale(np.asarray(data[f"scale_{i}"]).astype(np.float32)))
        rot = np.stack([np.asarray(data[f"rot_{i}"]).astype(np.float32).astype(np.float64) for i in range(4)], 1)
        ok &= np.nan_to_num(np.linalg.norm(rot, axis=1)) > 0
        if LABEL_PROP in names:
            ok &= _label_ok(data)
        if INTERIOR_PROP in names:
            ok &= _interior_ok(data)
    return ok


def load_ply_lenient(path, device="cpu") -> tuple[GaussianSet, int]:
    """`load_ply` that drops the Gaussians with NaN/inf values, degenerate scales or zero quaternions
    (a trainer's stray output) instead of refusing the file: (Gaussians, how many were dropped).
    Raises PlyError when the file is malformed or nothing usable is left."""
    path = as_path("load_ply_lenient", path)
    as_device("load_ply_lenient", device)
    data, names = _read_vertex(path)
    _require(path, names, _REQUIRED)
    ok = _usable_rows(data, names)
    if not ok.any():
        raise _fail(path, f"none of its {len(data)} Gaussians has finite values, scales and rotations; export it again")
    return load_ply(path, device, _rows=np.flatnonzero(ok) if not ok.all() else None), int((~ok).sum())


_REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2"] + [
    f"rot_{i}" for i in range(4)
]


def _not_another_format(path) -> None:
    """A .splat, .spz or compressed PLY handed to load_ply: name the reader that takes it (plyfile's own error,
    a codec failure or a missing f_dc_0, said nothing of the kind)."""
    try:
        fmt = detect_format(path)
    except PlyError:
        return  # not a splat file at all: _read_vertex says what is wrong with it
    if fmt != "ply":
        raise _fail(
            path,
            f"is a {fmt} file, not a 3DGS .ply; read it with fracture_gs.io.formats.read_gaussians (every format) "
            "or pass it as a config's scene",
        )


def load_ply(path, device="cpu", _rows=None) -> GaussianSet:
    """Read a 3DGS PLY into a `GaussianSet` with activated values (exp scales, sigmoid opacities,
    normalized wxyz quaternions, SH [N, K, 3] DC first); raises `PlyError` on malformed input."""
    path = as_path("load_ply", path)
    as_device("load_ply", device)
    if _rows is None:
        _not_another_format(path)
    data, names = _read_vertex(path)
    scale_n = [f"scale_{i}" for i in range(3)]
    rot_n = [f"rot_{i}" for i in range(4)]
    dc_n = [f"f_dc_{i}" for i in range(3)]
    _require(path, names, _REQUIRED)
    if _rows is not None:
        data = data[_rows]
    rest_n = _rest_names(path, names)

    cols = lambda ns: np.stack([_column(path, data, n) for n in ns], axis=1)  # noqa: E731
    means, dc = cols(["x", "y", "z"]), cols(dc_n)  # [N, 3] each
    rest = cols(rest_n) if rest_n else np.zeros((len(data), 0), np.float32)  # [N, 3(K-1)]
    raw_scale, raw_rot = cols(scale_n), cols(rot_n)
    raw_opacity = _column(path, data, "opacity")
    scales = activate_scale(raw_scale)
    _check_scales(path, raw_scale, scales)
    _check_rots(path, raw_rot)

    n, k1 = len(data), len(rest_n) // 3
    sh = np.concatenate([dc[:, None, :], rest.reshape(n, 3, k1).transpose(0, 2, 1)], axis=1)
    used = {"x", "y", "z", *dc_n, *rest_n, "opacity", *scale_n, *rot_n, INTERIOR_PROP, LABEL_PROP}
    extra = {}
    for name in names:
        if name not in used:
            t = _extra_tensor(path, data, name, device)
            if t is not None:
                extra[name] = t

    t = lambda a: torch.from_numpy(np.ascontiguousarray(a)).to(device)  # noqa: E731
    gs = GaussianSet(
        means=t(means),
        quats=t(_activate_rot(raw_rot)),
        scales=t(scales),
        opacities=t(activate_opacity(raw_opacity)),
        sh=t(sh),
        interior=t(_interior(path, data)) if INTERIOR_PROP in names else None,
        labels=t(_labels(path, data)) if LABEL_PROP in names else None,
        extra=extra,
    )
    gs.__dict__["_ply_raw"] = _RawCache(
        scale=raw_scale,
        opacity=raw_opacity,
        rot=raw_rot,
        order=names,
        had_normals=all(p in names for p in NORMAL_PROPS),
        had_interior=INTERIOR_PROP in names,
        had_label=LABEL_PROP in names,
    )
    return gs


# ----------------------------------------------------------------------------- writing


def _np(x: torch.Tensor) -> np.ndarray:
    return x.detach().cpu().numpy()


def _raw_fields(gs: GaussianSet) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Raw (file) scale [N,3], opacity [N], rot [N,4]: cached raw values where the activated
    values are unchanged since `load_ply`, the float64 inverse elsewhere."""
    scales = _np(gs.scales).astype(np.float32)
    opac = _np(gs.opacities).astype(np.float32)
    quats = _np(gs.quats).astype(np.float32)
    scale_raw, opac_raw, rot_raw = inverse_scale(scales), inverse_opacity(opac), quats.copy()
    cache = gs.__dict__.get("_ply_raw")
    if cache is not None and len(cache.opacity) == len(gs):
        keep = (activate_scale(cache.scale) == scales).all(axis=1)
        scale_raw[keep] = cache.scale[keep]
        keep = activate_opacity(cache.opacity) == opac
        opac_raw[keep] = cache.opacity[keep]
        keep = (_activate_rot(cache.rot) == quats).all(axis=1)
        rot_raw[keep] = cache.rot[keep]
    return scale_raw, opac_raw, rot_raw


def _check_writable(gs: GaussianSet, path) -> None:
    s, q = _np(gs.scales), _np(gs.quats)
    if not (np.isfinite(s).all() and (s > 0).all()):
        raise _fail(
            path,
            "cannot write field 'scales': it has zero, negative or non-finite values; "
            "clamp the scales to positive finite values first",
        )
    if not (np.isfinite(q).all() and (np.linalg.norm(q, axis=1) > 0).all()):
        raise _fail(path, "cannot write field 'quats': it has zero or non-finite quaternions; normalize them first")
    for name, v in gs.extra.items():
        if not torch.is_tensor(v) or v.ndim != 1 or len(v) != len(gs):
            raise _fail(
                path,
                f"cannot write extra property '{name}': it must be a [N] tensor with "
                f"N = {len(gs)}; reshape or drop it from gs.extra",
            )


def _columns(gs: GaussianSet, normals) -> dict:
    """Property name -> [N] numpy column, in the standard 3DGS order, then extras."""
    n, k = len(gs), gs.sh.shape[1]
    if k not in (1, 4, 9, 16):
        raise PlyError(f"GaussianSet.sh has K = {k} coefficients; use (degree+1)^2 with degree 0-3")
    cols = {a: c for a, c in zip("xyz", _np(gs.means).astype(np.float32).T)}
    extra = dict(gs.extra)
    cache = gs.__dict__.get("_ply_raw")
    if normals is None:
        normals = cache.had_normals if cache is not None else True
    if normals or all(p in extra for p in NORMAL_PROPS):
        for p in NORMAL_PROPS:
            cols[p] = _np(extra.pop(p)) if p in extra else np.zeros(n, np.float32)
    sh = _np(gs.sh).astype(np.float32)  # [N, K, 3]
    cols.update({f"f_dc_{c}": sh[:, 0, c] for c in range(3)})
    rest = sh[:, 1:, :].transpose(0, 2, 1).reshape(n, 3 * (k - 1))  # channel-major
    cols.update({f"f_rest_{i}": rest[:, i] for i in range(rest.shape[1])})
    scale_raw, opac_raw, rot_raw = _raw_fields(gs)
    cols["opacity"] = opac_raw
    cols.update({f"scale_{i}": scale_raw[:, i] for i in range(3)})
    cols.update({f"rot_{i}": rot_raw[:, i] for i in range(4)})
    cols.update({name: _np(v) for name, v in extra.items()})
    interior, labels = _np(gs.interior).astype(bool), _np(gs.labels)
    if interior.any() or (cache is not None and cache.had_interior):
        cols[INTERIOR_PROP] = interior.astype(np.uint8)
    if (labels != 0).any() or (cache is not None and cache.had_label):
        cols[LABEL_PROP] = labels.astype(np.int32)
    if cache is not None and set(cache.order) == set(cols):
        cols = {name: cols[name] for name in cache.order}  # keep the source file's order
    return cols


_PLY_CAST = {"b": np.uint8, "i8": np.int32, "u8": np.uint32, "f2": np.float32}


def _ply_column(c: np.ndarray) -> np.ndarray:  # [N]
    """A column in a dtype PLY can hold (bool -> u1, int64 -> i4, uint64 -> u4, f2 -> f4)."""
    key = "b" if c.dtype == bool else f"{c.dtype.kind}{c.dtype.itemsize}"
    return c.astype(_PLY_CAST[key]) if key in _PLY_CAST else c


def save_ply(gs: GaussianSet, path, normals: bool | None = None) -> None:
    """Write `gs` as a binary little-endian 3DGS PLY (inverse activations; see the module doc).

    `normals`: write nx ny nz (zeros unless `gs.extra` holds them); None = as in the source file
    for a set from `load_ply`, else yes (the INRIA layout that fixed-layout viewers expect)."""
    gs = as_gaussians("save_ply", gs)
    path = as_path("save_ply", path)
    if normals is not None and not isinstance(normals, bool):
        raise ArgumentError(
            f"save_ply: normals = {normals!r:.40} is not True, False or None; pass normals=True to write nx ny nz, "
            "False to leave them out, or None (as in the source file)."
        )
    named = named_format(path)
    if named not in (None, "ply"):
        other = SUFFIX.get(named, f".{named}")
        raise PlyError(
            f"save_ply: {os.path.basename(path)} ends in {other}, but save_ply writes a 3DGS .ply, which viewers "
            f"going by the name would misread; name it {os.path.basename(path)[: -len(other)]}.ply, or use "
            "fracture_gs.io.write_gaussians(gs, path, fmt) for that format."
        )
    _check_writable(gs, path)
    cols = _columns(gs, normals)
    cols = {name: _ply_column(c) for name, c in cols.items()}
    arr = np.empty(len(gs), dtype=[(name, c.dtype.newbyteorder("<")) for name, c in cols.items()])
    for name, c in cols.items():
        arr[name] = c
    try:
        PlyData([PlyElement.describe(arr, "vertex")], byte_order="<").write(path)
    except OSError as err:
        raise write_failed(path, err) from None
