"""Every splat file format in and out: read it, write it (what a file is, by its bytes: `detect`, whose names
are re-exported here).

`read_gaussians(path)` returns the Gaussians in the package's activated convention, PLY axes (RDF),
with the rows that hold NaN/inf, degenerate scales or a zero quaternion dropped and counted, as
`load_ply_lenient` does for a 3DGS PLY (which still reads those). A quantised file keeps its precision:
its SH degree is what it stores, nothing is invented.

`write_gaussians(gs, path, fmt)` writes one of FORMATS. What each keeps:

    ply              everything, float32; save_ply(load_ply(f)) is bit for bit; extra properties,
                     material labels and interior flags travel as vertex properties
    compressed-ply   SH up to degree 3 but quantised (position/scale 11-10-11 bits of each 256-Gaussian
                     chunk's bounds, colour and opacity 8 bits, rotation 10 bits a component, SH rest 8 bits
                     over ±4); the Gaussians are reordered along a Z curve; no extra properties
    splat            means and scales exact; DC colour only (no SH rest), colour and opacity 8 bits,
                     rotation 8 bits a component; no extra properties
    spz              SH up to degree 3 but quantised (positions 1/4096 unit, log-scales 1/16, colour and
                     opacity 8 bits, rotation 9 bits, SH rest 8 bits over ±1); no extra properties
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import torch

from ..errors import PlyError
from . import gsply_io, splat_file
from .detect import (
    FORMATS,
    READ,
    SCENE_SUFFIXES,
    SUFFIX,
    as_path,
    detect_format,
    is_splat_file,
    named_format,
    ply_header,
    refuse,
    spz_header,
)
from .gaussian_set import GaussianSet
from .ply import SIGMA_RANGE, as_device, as_gaussians, load_ply_lenient, save_ply, write_failed

__all__ = [
    "FORMATS",
    "READ",
    "SCENE_SUFFIXES",
    "SUFFIX",
    "detect_format",
    "is_splat_file",
    "read_gaussians",
    "spz_header",
    "write_gaussians",
]
_COMPRESSED_CHUNK_PROPS = 18  # min/max of position, log-scale and colour


# ----------------------------------------------------------------------------- reading


def _usable(a: dict) -> np.ndarray:  # [N] bool
    """Rows load_ply would accept: finite values, σ within SIGMA_RANGE, a non-zero quaternion."""
    with np.errstate(invalid="ignore", over="ignore"):
        ok = np.isfinite(a["means"]).all(1) & np.isfinite(a["sh"]).all((1, 2)) & np.isfinite(a["opacities"])
        s = a["scales"].astype(np.float64)
        ok &= (np.isfinite(s) & (s >= SIGMA_RANGE[0]) & (s <= SIGMA_RANGE[1])).all(1)
        q = a["quats"].astype(np.float64)
        ok &= np.isfinite(q).all(1) & (np.nan_to_num(np.linalg.norm(q, axis=1)) > 0)
    return ok


def _compressed_layout(path, head: bytes) -> None:
    """One sentence for a compressed PLY whose layout gsply cannot decode or whose data is cut off."""
    elements, header_len = ply_header(head)
    chunks, chunk_props = elements["chunk"]
    n, vertex = elements["vertex"]
    sh_props = len(elements.get("sh", (0, []))[1])
    if len(chunk_props) != _COMPRESSED_CHUNK_PROPS or vertex != [
        "packed_position",
        "packed_rotation",
        "packed_scale",
        "packed_color",
    ]:
        raise refuse(
            path,
            f"is a compressed PLY of an early layout ({len(chunk_props)} chunk bounds, not 18 with colour)",
            "open and save it again in SuperSplat, or convert it with splat-transform",
        )
    fmt = next(
        (
            ln.split()[1:2]
            for ln in head[:header_len].decode("ascii", "replace").splitlines()
            if ln.startswith("format ")
        ),
        [""],
    )
    if fmt != ["binary_little_endian"]:
        raise PlyError(
            f"{path}: is a compressed PLY in format {' '.join(fmt) or 'none'!r}, but compressed PLYs are "
            "binary_little_endian (their packed fields mean nothing else); export it again from SuperSplat."
        )
    sh_rows = elements.get("sh", (n, []))[0]
    if sh_rows != n:
        raise PlyError(
            f"{path}: the compressed PLY's sh element has {sh_rows:,} rows for its {n:,} Gaussians (one each); "
            "download or export it again."
        )
    need = header_len + 4 * chunks * len(chunk_props) + 16 * n + n * sh_props
    have = os.path.getsize(path)
    if have < need or chunks != -(-n // 256):
        raise PlyError(
            f"{path}: the compressed PLY is cut off or inconsistent ({n:,} Gaussians in {chunks} chunks need "
            f"{need:,} bytes, the file has {have:,}); download or export it again."
        )


def _spz_layout(path) -> None:
    """One sentence for a gzip SPZ (versions 2 and 3) whose header disagrees with its data: gsply reads the
    header's count and SH degree and decodes whatever bytes follow, so a count that is too small, a v3 file
    relabelled v2 or a degree that is not the data's came back as Gaussians built from the wrong bytes."""
    with open(path, "rb") as fh:
        if fh.read(2) != b"\x1f\x8b":
            return  # v4 (NGSP, zstd streams): gsply checks each stream's length
        fh.seek(0)
        inflate, total, head = zlib.decompressobj(16 + zlib.MAX_WBITS), 0, b""
        try:
            while chunk := fh.read(1 << 20):
                out = inflate.decompress(chunk)
                head = head if len(head) >= 16 else (head + out)[:16]
                total += len(out)
                if inflate.eof:
                    break
        except zlib.error:
            return  # a broken container: gsply names it
    if len(head) < 16 or not inflate.eof:
        return
    version, n, degree = struct.unpack_from("<IIB", head, 4)
    sh_values = 3 * ((degree + 1) ** 2 - 1)
    need = 16 + n * (9 + 1 + 3 + 3 + (3 if version == 2 else 4) + sh_values)
    if total != need:
        raise PlyError(
            f"{path}: the SPZ header (version {version}, {n:,} Gaussians, SH degree {degree}) needs {need:,} "
            f"bytes of data but the file holds {total:,}, so header and data disagree; export it again from its "
            "source."
        )


def _arrays(path, fmt: str) -> dict:
    if fmt == "compressed-ply":
        with open(path, "rb") as fh:
            _compressed_layout(path, fh.read(65536))
        return gsply_io.read_compressed_ply(path)
    if fmt == "spz":
        _spz_layout(path)
        return gsply_io.read_spz(path)
    raw = Path(path).read_bytes()
    if len(raw) % splat_file.ROW_BYTES:
        raise PlyError(f"{path}: a .splat file holds 32-byte rows, but its {len(raw):,} bytes are no multiple of 32.")
    return splat_file.decode(raw)


def read_gaussians(path, device="cpu") -> tuple[GaussianSet, int, str]:
    """(Gaussians, rows dropped as unreadable, format name) of any splat file FORMATS lists.
    Raises PlyError for other files, a `.ksplat`, and files with no usable Gaussian."""
    path = as_path("read_gaussians", path)
    as_device("read_gaussians", device)
    fmt = detect_format(path)
    if fmt == "ksplat":
        raise PlyError(
            f"{path}: is a .ksplat file (mkkellogg's GaussianSplats3D), which has no maintained Python reader; "
            "convert it to .ply with SuperSplat (superspl.at/convert) or splat-transform "
            f"(npx @playcanvas/splat-transform in.ksplat out.ply) and pass that ({READ} are read)."
        )
    if fmt == "ply":
        gs, dropped = load_ply_lenient(path, device)
        return gs, dropped, fmt
    a = _arrays(path, fmt)
    ok = _usable(a)
    if not ok.any():
        raise PlyError(
            f"{path}: none of its {len(ok)} Gaussians has finite values, scales and rotations; export it again."
        )
    t = lambda x: torch.from_numpy(np.ascontiguousarray(x[ok])).to(device)  # noqa: E731
    gs = GaussianSet(
        means=t(a["means"]), quats=t(a["quats"]), scales=t(a["scales"]), opacities=t(a["opacities"]), sh=t(a["sh"])
    )
    return gs, int((~ok).sum()), fmt


# ----------------------------------------------------------------------------- writing


def _checked(gs: GaussianSet, path) -> dict:
    """The activated arrays of `gs` (CPU numpy), refusing values no format can hold."""
    a = {
        "means": gs.means.detach().cpu().float().numpy(),
        "scales": gs.scales.detach().cpu().float().numpy(),
        "quats": gs.quats.detach().cpu().float().numpy(),
        "opacities": gs.opacities.detach().cpu().float().numpy(),
        "sh": gs.sh.detach().cpu().float().numpy(),
    }
    if a["sh"].shape[1] not in (1, 4, 9, 16):
        raise PlyError(f"{path}: GaussianSet.sh has K = {a['sh'].shape[1]} coefficients; use (degree+1)^2, degree 0-3.")
    bad = ~_usable(a)
    if bad.any():
        raise PlyError(
            f"{path}: cannot write {int(bad.sum())} Gaussians with non-finite values, zero or non-finite scales or "
            "zero quaternions; drop them first (GaussianSet.subset)."
        )
    return a


def write_gaussians(gs: GaussianSet, path, fmt: str = "ply") -> Path:
    """Write `gs` to `path` in one of FORMATS (what each keeps: the module doc); returns the path."""
    gs = as_gaussians("write_gaussians", gs)
    path = Path(as_path("write_gaussians", path))
    if not isinstance(fmt, str) or fmt not in FORMATS:
        raise PlyError(f"write_gaussians: format {fmt!r} is not written; choose one of {', '.join(FORMATS)}.")
    named = named_format(path)
    if named is not None and named != fmt and not (fmt == "compressed-ply" and named == "ply"):
        raise PlyError(
            f"write_gaussians: {path.name} names a {named} file, but fmt = {fmt!r} writes {fmt}, which viewers "
            f"going by the name would misread; name it {path.name[: -len(SUFFIX.get(named, path.suffix))]}"
            f"{SUFFIX[fmt]} or pass fmt={named!r}."
        )
    if fmt == "ply":
        save_ply(gs if gs.device.type == "cpu" else gs.to("cpu"), path)  # a CPU set keeps load_ply's raw values
        return path
    if len(gs) == 0:  # compressed-ply and spz took the bounds of nothing (a numpy traceback); splat wrote 0 bytes
        raise PlyError(
            f"write_gaussians: gs holds no Gaussians, and a {fmt} file of none cannot be read back; write at least "
            "one Gaussian (or format 'ply')."
        )
    a = _checked(gs, path)
    try:
        if fmt == "splat":
            path.write_bytes(splat_file.encode(a["means"], a["scales"], a["quats"], a["opacities"], a["sh"][:, 0]))
        elif fmt == "compressed-ply":
            gsply_io.write_compressed_ply(a, path)
        else:
            gsply_io.write_spz(a, path)
    except OSError as err:
        raise write_failed(path, err) from None
    return path
