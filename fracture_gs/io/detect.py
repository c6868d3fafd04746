"""What a splat file is, from its bytes, and whether a scene path names one: the part of `formats` that needs
neither torch nor numpy, so that loading a config (`io.config`) and the CLI's parser stay light.

`detect_format(path)` looks at the content, never at the suffix (a `.splat` renamed `.ply` is still a
`.splat`): "ply" (a 3DGS PLY as the Inria trainer writes it), "compressed-ply" (PlayCanvas/SuperSplat),
"spz" (Niantic, versions 2-4), "splat" (antimatter15) or "ksplat" (recognised only to refuse it). Anything
else is a `PlyError` naming what the file looks like and the formats that are read. Only a file with no
magic number at all, a `.splat` candidate, imports numpy (`splat_file.plausible_rows`).
"""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import tomllib

from ..errors import ArgumentError, PlyError

FORMATS = ("ply", "compressed-ply", "splat", "spz")
"""The formats read and written (`--export-format`)."""
SUFFIX = {"ply": ".ply", "compressed-ply": ".compressed.ply", "splat": ".splat", "spz": ".spz"}
SCENE_SUFFIXES = (".ply", ".splat", ".spz", ".ksplat")
"""Suffixes taken as a scene without looking inside (`.compressed.ply` ends in `.ply`)."""
READ = "3DGS .ply, compressed .ply (SuperSplat/PlayCanvas), .splat (antimatter15) and .spz (Niantic)"
_GAUSSIAN_PROPS = ("f_dc_0", "opacity", "scale_0", "rot_0")
SPLAT_ROW_BYTES = 32  # splat_file.ROW_BYTES (a test checks they agree)
_IMAGES = {
    b"\x89PNG\r\n\x1a\n": "a PNG image",
    b"\xff\xd8\xff": "a JPEG image",
    b"GIF87a": "a GIF image",
    b"GIF89a": "a GIF image",
    b"II*\x00": "a TIFF image",
    b"MM\x00*": "a TIFF image",
    b"\x76\x2f\x31\x01": "an OpenEXR image",
}


def as_path(where: str, value, name: str = "path") -> str:
    """A path argument of the public functions as str (str, bytes or os.PathLike); another type or an empty
    path is an ArgumentError naming `where`'s argument `name`."""
    try:
        text = os.fsdecode(value) if isinstance(value, (str, bytes, os.PathLike)) else None
    except (TypeError, UnicodeDecodeError):
        text = None
    if text is None:
        raise ArgumentError(
            f"{where}: {name} must be a file path (str or pathlib.Path), got {type(value).__name__} {value!r:.40}; "
            "pass e.g. 'scene.ply'."
        )
    if not text.strip():
        raise ArgumentError(f"{where}: {name} is empty; pass the file's path, e.g. 'scene.ply'.")
    return text


def refuse(path, what: str, fix: str = "") -> PlyError:
    """The one sentence for a file that is not a splat file this package reads: what it is, and the fix."""
    fix = fix or "pass a splat file in one of those formats"
    return PlyError(f"{path}: {what}, not Gaussians this package reads ({READ}); {fix}.")


def ply_header(head: bytes):
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
    parsed = ply_header(head)
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
    raise refuse(
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
            raise refuse(path, "is gzip-compressed data without an SPZ header", "decompress it and pass what it holds")
    else:
        inner = head
    if len(inner) < 16:
        raise refuse(path, "is an SPZ file cut off inside its header", "download or export it again")
    _, version, n, degree, bits = struct.unpack_from("<IIIBB", inner)
    if version == 1:
        raise refuse(
            path,
            "is an SPZ version 1 file (float16 positions), an early layout that is not read",
            "re-save it with a current SPZ tool (versions 2-4 are read)",
        )
    if not 2 <= version <= 4 or degree > 3 or (head[:2] == b"\x1f\x8b") != (version < 4):
        raise refuse(path, f"is an SPZ file of version {version} with SH degree {degree}", "save it as SPZ 2-4")
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
    if any(ord(ch) < 32 and ch not in "\t\n\r\f\v" or ord(ch) == 127 for ch in text[:4096]):
        return None  # control bytes (0x01-0x1f, 0x7f) are binary data, not text a user wrote
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
        raise refuse(path, "is empty (0 bytes)", "export the scene again")
    with open(path, "rb") as fh:
        head = fh.read(65536)
    if head.startswith((b"ply\n", b"ply\r")):
        return _ply_kind(path, head)
    if head[:4] == b"NGSP" or head[:2] == b"\x1f\x8b":
        spz_header(path, head)
        return "spz"
    for magic, what in _IMAGES.items():
        if head.startswith(magic):
            raise refuse(path, f"is {what}", "pass the splat file the images were trained into")
    if head[:4] == b"RIFF" and head[8:12] == b"WEBP":
        raise refuse(path, "is a WebP image", "pass the splat file the images were trained into")
    if head[:4] == b"PK\x03\x04":
        raise refuse(
            path,
            "is a ZIP archive (a PlayCanvas .sog bundle is one)",
            "convert it to .ply with splat-transform (npx @playcanvas/splat-transform in.sog out.ply)",
        )
    if head[:4] == b"glTF":
        raise refuse(path, "is a binary glTF model", "export the scene's Gaussians as .ply")
    if _is_ksplat(head, size):
        return "ksplat"
    text = _text_kind(head, path)
    if text is not None:
        raise refuse(path, f"is {text}", "pass a config under a .toml name, a scene as one of those formats")
    # `.splat` has no magic number: a headerless run of 32-byte rows is accepted when nearly every
    # sampled row decodes to a Gaussian (finite means, positive finite scales, non-zero quaternion).
    # Binary data that happens to look like that would be misread; nothing else can tell.
    share = 0.0
    if size % SPLAT_ROW_BYTES == 0:
        share = _plausible_splat(path)
        if share >= 0.9:
            return "splat"
    if path.lower().endswith(".splat") and (size % SPLAT_ROW_BYTES or share >= 0.1):  # a .splat, cut or damaged
        if size % SPLAT_ROW_BYTES:
            raise PlyError(
                f"{path}: a .splat file holds 32-byte rows, but its {size:,} bytes are no multiple of 32 (cut off, "
                "or not a .splat); download or export it again."
            )
        raise PlyError(
            f"{path}: only {share:.0%} of the sampled 32-byte rows of this .splat decode to Gaussians (finite "
            "positions, scales of 1e-12 to 1e6, a non-zero rotation), so it is damaged or not a .splat; export it "
            "again."
        )
    raise refuse(path, f"is binary data of {size:,} bytes in no format recognised")


def named_format(path) -> str | None:
    """The splat format a file name's suffix names ("compressed-ply" for `.compressed.ply`, "ksplat" too), or None
    (the writers refuse a name that names another format than they write)."""
    name = str(path).lower()
    if name.endswith(".compressed.ply"):
        return "compressed-ply"
    return {".ply": "ply", ".splat": "splat", ".spz": "spz", ".ksplat": "ksplat"}.get(Path(name).suffix)


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


def _plausible_splat(path) -> float:
    """`splat_file.plausible_rows` of the file, mapped (numpy is imported here, only for such files)."""
    import numpy as np

    from . import splat_file

    return splat_file.plausible_rows(np.memmap(path, np.uint8, "r"))
