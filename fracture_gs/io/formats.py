"""Every splat file format in and out: what a file is (by its bytes), read it, write it.

`detect_format(path)` looks at the content, never at the suffix (a `.splat` renamed `.ply` is still a
`.splat`): "ply" (a 3DGS PLY as the Inria trainer writes it), "compressed-ply" (PlayCanvas/SuperSplat),
"spz" (Niantic, versions 2-4), "splat" (antimatter15) or "ksplat" (recognised only to refuse it). Anything
else is a `PlyError` naming what the file looks like and the formats that are read.

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
import tomllib
import torch

from ..errors import PlyError
from . import gsply_io, splat_file
from .gaussian_set import GaussianSet
from .ply import SIGMA_RANGE, as_device, as_gaussians, as_path, load_ply_lenient, save_ply, write_failed

FORMATS = ("ply", "compressed-ply", "splat", "spz")
"""The formats read and written (`--export-format`)."""
SUFFIX = {"ply": ".ply", "compressed-ply": ".compressed.ply", "splat": ".splat", "spz": ".spz"}
SCENE_SUFFIXES = (".ply", ".splat", ".spz", ".ksplat")
"""Suffixes taken as a scene without looking inside (`.compressed.ply` ends in `.ply`)."""
READ = "3DGS .ply, compressed .ply (SuperSplat/PlayCanvas), .splat (antimatter15) and .spz (Niantic)"
_GAUSSIAN_PROPS = ("f_dc_0", "opacity", "scale_0", "rot_0")
_COMPRESSED_CHUNK_PROPS = 18  # min/max of position, log-scale and colour
_IMAGES = {
    b"\x89PNG\r\n\x1a\n": "a PNG image",
    b"\xff\xd8\xff": "a JPEG image",
    b"GIF87a": "a GIF image",
    b"GIF89a": "a GIF image",
    b"II*\x00": "a TIFF image",
    b"MM\x00*": "a TIFF image",
    b"\x76\x2f\x31\x01": "an OpenEXR image",
}


def _refuse(path, what: str, fix: str = "") -> PlyError:
    fix = fix or "pass a splat file in one of those formats"
    return PlyError(f"{path}: {what}, not Gaussians this package reads ({READ}); {fix}.")


# ----------------------------------------------------------------------------- detection


def _ply_header(head: bytes):
    """(elements {name: (count, [property names])}, header bytes) of a PLY, or None if no end_header
    is found in `head`."""
    end = head.find(b"end_header")
    if end < 0:
        return None
    stop = head.find(b"\n", end)
    header_len = (stop + 1) if stop >= 0 else len(head)
    elements, current = {}, None
    for line in head[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if len(words) >= 3 and words[0] == "element":
            current = words[1]
            elements[current] = (int(words[2]) if words[2].isdigit() else -1, [])
        elif len(words) >= 3 and words[0] == "property" and current is not None:
            elements[current][1].append(words[-1])
    return elements, header_len


def _ply_kind(path, head: bytes) -> str:
    parsed = _ply_header(head)
    if parsed is None:
        return "ply"  # a broken header: load_ply says what is wrong with it
    elements, _ = parsed
    vertex = elements.get("vertex", (0, []))[1]
    if "chunk" in elements and "packed_position" in vertex:
        return "compressed-ply"
    if "vertex" not in elements:
        return "ply"  # load_ply names the missing element
    if any(p in vertex for p in _GAUSSIAN_PROPS):
        return "ply"
    shown = ", ".join(vertex[:6]) + (", ..." if len(vertex) > 6 else "")
    others = [e for e in elements if e != "vertex"]
    kind = "a mesh" if "face" in others else "a point cloud"
    raise _refuse(
        path,
        f"is a PLY {kind} (its vertices have {shown or 'no properties'}, none of the Gaussian properties "
        "f_dc_0, opacity, scale_0, rot_0)",
        "export the scene's Gaussians from the splatting trainer or editor",
    )


def spz_header(path, head: bytes) -> tuple[int, int, int, int]:
    """(version, Gaussians, SH degree, fractional bits) of an SPZ file; PlyError if it is not one."""
    if head[:2] == b"\x1f\x8b":
        try:
            inner = zlib.decompressobj(16 + zlib.MAX_WBITS).decompress(head, 16)
        except zlib.error:
            inner = b""
        if inner[:4] != b"NGSP":
            raise _refuse(path, "is gzip-compressed data without an SPZ header", "decompress it and pass what it holds")
    else:
        inner = head
    if len(inner) < 16:
        raise _refuse(path, "is an SPZ file cut off inside its header", "download or export it again")
    _, version, n, degree, bits = struct.unpack_from("<IIIBB", inner)
    if version == 1:
        raise _refuse(
            path,
            "is an SPZ version 1 file (float16 positions), an early layout that is not read",
            "re-save it with a current SPZ tool (versions 2-4 are read)",
        )
    if not 2 <= version <= 4 or degree > 3 or (head[:2] == b"\x1f\x8b") != (version < 4):
        raise _refuse(path, f"is an SPZ file of version {version} with SH degree {degree}", "save it as SPZ 2-4")
    return version, n, degree, bits


def _is_ksplat(head: bytes, size: int) -> bool:
    """mkkellogg's GaussianSplats3D `.ksplat`: no magic; a 4096-byte header starting with version 0.x
    (uint8 major 0, minor ≤ 9), then uint32 max sections, sections, max splats, splats and a uint16
    compression level 0-2 (the layout of its SplatBuffer), followed by 1024-byte section headers."""
    if size < 4096 + 1024 or len(head) < 24 or head[0] != 0 or head[1] > 9 or head[2:4] != b"\0\0":
        return False
    max_sections, sections, max_splats, splats = struct.unpack_from("<4I", head, 4)
    level = struct.unpack_from("<H", head, 20)[0]
    return (
        1 <= sections <= max_sections <= 1 << 16
        and 1 <= splats <= max_splats
        and level <= 2
        and size >= 4096 + 1024 * max_sections
    )


def _text_kind(head: bytes, path) -> str | None:
    """'TOML text' / 'text' when the start of the file is UTF-8 text, else None."""
    if b"\0" in head:
        return None
    for cut in range(4):  # the 64 KiB window may end inside a multi-byte character
        try:
            text = head[: len(head) - cut].decode("utf-8-sig")
            break
        except UnicodeDecodeError:
            continue
    else:
        return None
    try:
        tomllib.loads(Path(path).read_text("utf-8-sig") if len(head) < 65536 else text)
        return "TOML text (a config?)"
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, RecursionError):
        first = next((ln.strip() for ln in text.splitlines() if ln.strip()), "")
        return f"text (first line {first[:40]!r})"


def detect_format(path) -> str:
    """The format of a splat file from its bytes: "ply", "compressed-ply", "spz", "splat" or "ksplat".
    Raises PlyError (one sentence: what the file looks like, the formats read, the fix) otherwise."""
    path = as_path("detect_format", path)
    if os.path.isdir(path):
        raise PlyError(f"{path}: is a folder, not a file; pass the scene file inside it ({READ} are read).")
    if not os.path.isfile(path):
        raise PlyError(f"{path}: no such file; check the path to the scene ({READ} are read).")
    size = os.path.getsize(path)
    if size == 0:
        raise _refuse(path, "is empty (0 bytes)", "export the scene again")
    with open(path, "rb") as fh:
        head = fh.read(65536)
    if head.startswith((b"ply\n", b"ply\r")):
        return _ply_kind(path, head)
    if head[:4] == b"NGSP" or head[:2] == b"\x1f\x8b":
        spz_header(path, head)
        return "spz"
    for magic, what in _IMAGES.items():
        if head.startswith(magic):
            raise _refuse(path, f"is {what}", "pass the splat file the images were trained into")
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        raise _refuse(path, "is a WebP image", "pass the splat file the images were trained into")
    if head[:4] == b"PK\x03\x04":
        raise _refuse(
            path,
            "is a ZIP archive (a PlayCanvas .sog bundle is one)",
            "convert it to .ply with splat-transform (npx @playcanvas/splat-transform in.sog out.ply)",
        )
    if head[:4] == b"glTF":
        raise _refuse(path, "is a binary glTF model", "export the scene's Gaussians as .ply")
    if _is_ksplat(head, size):
        return "ksplat"
    text = _text_kind(head, path)
    if text is not None:
        raise _refuse(path, f"is {text}", "pass a config under a .toml name, a scene as one of those formats")
    # `.splat` has no magic number: a headerless run of 32-byte rows is accepted when nearly every
    # sampled row decodes to a Gaussian (finite means, positive finite scales, non-zero quaternion).
    # Binary data that happens to look like that would be misread; nothing else can tell.
    if size % splat_file.ROW_BYTES == 0 and splat_file.plausible_rows(np.memmap(path, np.uint8, "r")) >= 0.9:
        return "splat"
    raise _refuse(path, f"is binary data of {size:,} bytes in no format recognised")


def is_splat_file(path) -> bool:
    """Whether a scene path names a splat file: its suffix is one of SCENE_SUFFIXES, or the file exists
    and its content is a splat format (whatever its suffix says)."""
    text = as_path("is_splat_file", path)
    if text.lower().endswith(SCENE_SUFFIXES):
        return True
    if not os.path.isfile(text):
        return False
    try:
        detect_format(text)
    except (PlyError, OSError):
        return False
    return True


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
    elements, header_len = _ply_header(head)
    chunks, chunk_props = elements["chunk"]
    n, vertex = elements["vertex"]
    sh_props = len(elements.get("sh", (0, []))[1])
    if len(chunk_props) != _COMPRESSED_CHUNK_PROPS or vertex != [
        "packed_position",
        "packed_rotation",
        "packed_scale",
        "packed_color",
    ]:
        raise _refuse(
            path,
            f"is a compressed PLY of an early layout ({len(chunk_props)} chunk bounds, not 18 with colour)",
            "open and save it again in SuperSplat, or convert it with splat-transform",
        )
    need = header_len + 4 * chunks * len(chunk_props) + 16 * n + n * sh_props
    have = os.path.getsize(path)
    if have < need or chunks != -(-n // 256):
        raise PlyError(
            f"{path}: the compressed PLY is cut off or inconsistent ({n:,} Gaussians in {chunks} chunks need "
            f"{need:,} bytes, the file has {have:,}); download or export it again."
        )


def _arrays(path, fmt: str) -> dict:
    if fmt == "compressed-ply":
        with open(path, "rb") as fh:
            _compressed_layout(path, fh.read(65536))
        return gsply_io.read_compressed_ply(path)
    if fmt == "spz":
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
    if fmt == "ply":
        save_ply(gs if gs.device.type == "cpu" else gs.to("cpu"), path)  # a CPU set keeps load_ply's raw values
        return path
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
