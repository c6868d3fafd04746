"""How the capture subsets in this folder were cut from the real files (README.md says where each comes from).

Every subset is a selection of whole Gaussians of the original with their bytes unchanged: no value is decoded
and encoded again, so each keeps the original's quantisation exactly. Only the container around them is new
(the counts in a header; the gzip or zstd streams of an SPZ). Rerun with the originals in one folder:

    python tests/data/captures/make_subsets.py /tmp/caps
"""

from __future__ import annotations

import gzip
import struct
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
BIKER_CHUNKS = range(0, 596, 30)  # 20 full chunks of 256 Gaussians spread over the biker (5,120 Gaussians)


def _header(raw: bytes) -> tuple[list[str], int]:
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    return raw[:end].decode("ascii").split("\n")[:-1], end


def compressed_ply(src: Path, dst: Path, chunks) -> np.ndarray:
    """The chunks `chunks` of a PlayCanvas compressed PLY (their bounds and rows as stored); returns the rows."""
    raw = src.read_bytes()
    lines, at = _header(raw)
    counts, props, order = {}, {}, []
    for ln in lines:
        w = ln.split()
        if w[0] == "element":
            order.append(w[1])
            counts[w[1]], props[w[1]] = int(w[2]), []
        elif w[0] == "property":
            props[order[-1]].append(w)
    assert order[:2] == ["chunk", "vertex"] and all(p[1] == "float" for p in props["chunk"])
    chunk = np.frombuffer(raw, "<f4", counts["chunk"] * len(props["chunk"]), at).reshape(counts["chunk"], -1)
    at += chunk.nbytes
    vertex = np.frombuffer(raw, "<u4", counts["vertex"] * 4, at).reshape(-1, 4)
    at += vertex.nbytes
    sh = None
    if "sh" in counts:
        sh = np.frombuffer(raw, "u1", counts["sh"] * len(props["sh"]), at).reshape(counts["sh"], -1)
    rows = np.concatenate([np.arange(c * 256, c * 256 + 256) for c in chunks])
    out = []
    for ln in lines:
        w = ln.split()
        if w[0] == "element":
            ln = f"element {w[1]} {len(chunks) if w[1] == 'chunk' else len(rows)}"
        out.append(ln)
        if w[0] == "format":
            picked = f"{chunks.start}:{chunks.stop}:{chunks.step}"
            out.append(f"comment fracture-gs test subset: chunks {picked} of {src.name}")
    body = [chunk[list(chunks)].tobytes(), vertex[rows].tobytes()] + ([sh[rows].tobytes()] if sh is not None else [])
    dst.write_bytes(("\n".join(out) + "\n").encode("ascii") + b"".join(body))
    return rows


def _spz_widths(version: int, sh_degree: int) -> list[int]:
    """Bytes a Gaussian in each SPZ section: positions, alphas, colours, scales, rotations, SH."""
    return [9, 1, 3, 3, 3 if version < 3 else 4, 3 * {0: 0, 1: 3, 2: 8, 3: 15}[sh_degree]]


def spz(src: Path, dst: Path, rows: np.ndarray) -> None:
    """The Gaussians `rows` of an SPZ file, each section's bytes as stored, in the same container version."""
    raw = src.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        payload = gzip.decompress(raw)
        magic, version, n, degree, bits, flags, res = struct.unpack_from("<IIIBBBB", payload)
        at, parts = 16, []
        for w in _spz_widths(version, degree):
            parts.append(np.frombuffer(payload, "u1", n * w, at).reshape(n, w)[rows].tobytes())
            at += n * w
        head = struct.pack("<IIIBBBB", magic, version, len(rows), degree, bits, flags, res)
        dst.write_bytes(gzip.compress(head + b"".join(parts), mtime=0))
        return
    import zstandard

    magic, version, n, degree, bits, flags, streams, toc = struct.unpack_from("<IIIBBBBI", raw)
    assert version == 4 and toc == 32, "extensions before the TOC are not handled here"
    sizes = [struct.unpack_from("<QQ", raw, toc + 16 * i) for i in range(streams)]
    at, bodies = toc + 16 * streams, []
    widths = [w for w in _spz_widths(version, degree) if w]
    for (packed, plain), w in zip(sizes, widths):
        data = zstandard.ZstdDecompressor().decompress(raw[at : at + packed], max_output_size=plain)
        bodies.append(np.frombuffer(data, "u1").reshape(n, w)[rows].tobytes())
        at += packed
    chunks = [zstandard.ZstdCompressor(level=12).compress(b) for b in bodies]
    head = struct.pack("<IIIBBBBI", magic, version, len(rows), degree, bits, flags, streams, toc) + raw[20:32]
    tocs = b"".join(struct.pack("<QQ", len(c), len(b)) for c, b in zip(chunks, bodies))
    dst.write_bytes(head + tocs + b"".join(chunks))


def splat(src: Path, dst: Path, step: int) -> None:
    """Every `step`-th 32-byte row of a .splat file."""
    dst.write_bytes(np.frombuffer(src.read_bytes(), "u1").reshape(-1, 32)[::step].tobytes())


def inria_ply(src: Path, dst: Path, step: int) -> None:
    """Every `step`-th vertex of a binary little-endian 3DGS PLY (one vertex element), bytes unchanged."""
    raw = src.read_bytes()
    lines, at = _header(raw)
    assert "format binary_little_endian 1.0" in lines and sum(ln.startswith("element") for ln in lines) == 1
    n = next(int(ln.split()[2]) for ln in lines if ln.startswith("element vertex"))
    width = (len(raw) - at) // n
    rows = np.frombuffer(raw, "u1", n * width, at).reshape(n, width)[::step]
    out = [f"element vertex {len(rows)}" if ln.startswith("element vertex") else ln for ln in lines]
    out.insert(2, f"comment fracture-gs test subset: every {step}th vertex of {src.name}")
    dst.write_bytes(("\n".join(out) + "\n").encode("ascii") + rows.tobytes())


def main(folder: Path) -> None:
    rows = compressed_ply(folder / "biker.compressed.ply", HERE / "biker_5k.compressed.ply", BIKER_CHUNKS)
    spz(folder / "biker.spz", HERE / "biker_5k.spz", rows)
    n = struct.unpack_from("<I", gzip.decompress((folder / "fourth_st.spz").read_bytes())[:16], 8)[0]
    spz(folder / "fourth_st.spz", HERE / "fourth_st_5k.spz", np.arange(0, n, 26))
    splat(folder / "luma-seal.splat", HERE / "luma_seal_5k.splat", 20)
    inria_ply(folder / "donut.inria.ply", HERE / "donut_5k.ply", 9)


if __name__ == "__main__":
    main(Path(sys.argv[1] if len(sys.argv) > 1 else "/tmp/caps"))
