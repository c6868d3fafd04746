"""Every splat format in and out (`fracture_gs.io.formats`), on real captures (tests/data/captures/README.md).

A file's format comes from its bytes, never its suffix; what is not a splat file gets one sentence saying what
it looks like. gsply's decoding of compressed PLY and SPZ is checked against decoders written here from the
formats' specifications; SPZ's RUB axes become PLY's RDF (positions, quaternions, SH); the SPZ and the
compressed PLY of one capture agree within their quantisation; every written format reads back within its own
quantisation (3DGS PLY bit for bit); unreadable rows are dropped and counted.
"""

from __future__ import annotations

import gzip
import math
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from fracture_gs.capture.transform import rotate_sh
from fracture_gs.errors import PlyError
from fracture_gs.io import gsply_io
from fracture_gs.io.formats import READ, detect_format, is_splat_file, read_gaussians, write_gaussians
from fracture_gs.io.gaussian_set import quat_to_matrix
from fracture_gs.io.ply import load_ply

DATA = Path(__file__).parent / "data" / "captures"
SH_C0 = 0.28209479177387814
D = np.diag([1.0, -1.0, -1.0])  # RUB <-> RDF: a half turn about x
RGB = (("r", 24), ("g", 16), ("b", 8))  # compressed PLY colour channels and their bit shifts
DC_MAX = 127.5 / (0.15 * 255)  # the largest SH DC an SPZ colour byte holds

pytestmark = pytest.mark.usefixtures("one_thread")

CAPTURES = {
    "guitar.compressed.ply": "compressed-ply",
    "biker_5k.compressed.ply": "compressed-ply",
    "biker_5k.spz": "spz",
    "fourth_st_5k.spz": "spz",
    "luma_seal_5k.splat": "splat",
    "donut_5k.ply": "ply",
}


# ----------------------------------------------------------------------------- decoders from the specs


def _header(raw: bytes):
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    elements = {}
    for line in raw[:end].decode("ascii").splitlines():
        w = line.split()
        if w[0] == "element":
            elements[w[1]] = [int(w[2]), []]
            last = w[1]
        elif w[0] == "property":
            elements[last][1].append(w[-1])
    return elements, end


def spec_compressed_ply(path: Path) -> dict:
    """PlayCanvas compressed PLY, decoded from its description: 256 Gaussians a chunk; position and log-scale
    are 11-10-11-bit fractions (x high bits) between the chunk's min and max; colour r, g, b, opacity 8 bits
    each (r high), colour between the chunk's colour bounds; rotation: 2 bits naming the largest component of
    (w, x, y, z), then the other three in order, 10 bits each, as (v / 1023 - 0.5) * √2."""
    raw = path.read_bytes()
    el, at = _header(raw)
    nc, n = el["chunk"][0], el["vertex"][0]
    chunk = np.frombuffer(raw, "<f4", nc * 18, at).reshape(nc, 18).astype(np.float64)
    c = dict(zip(el["chunk"][1], chunk.T))
    packed = np.frombuffer(raw, "<u4", n * 4, at + chunk.size * 4).reshape(n, 4).astype(np.int64)
    k = np.arange(n) // 256

    def unorm(v, shift, bits):
        return ((v >> shift) & ((1 << bits) - 1)) / ((1 << bits) - 1)

    def lerp(v, lo, hi):
        fx, fy, fz = unorm(v, 21, 11), unorm(v, 11, 10), unorm(v, 0, 11)
        return np.stack([c[lo + a][k] + f * (c[hi + a][k] - c[lo + a][k]) for a, f in zip("xyz", (fx, fy, fz))], 1)

    means = lerp(packed[:, 0], "min_", "max_")
    log_scales = lerp(packed[:, 2], "min_scale_", "max_scale_")
    col = packed[:, 3]
    rgb = np.stack([c[f"min_{h}"][k] + unorm(col, s, 8) * (c[f"max_{h}"][k] - c[f"min_{h}"][k]) for h, s in RGB], 1)
    rot = packed[:, 1]
    largest = rot >> 30
    small = np.stack([(unorm(rot, s, 10) - 0.5) * math.sqrt(2) for s in (20, 10, 0)], 1)
    q = np.zeros((n, 4))
    for i in range(4):
        sel = largest == i
        others = [j for j in range(4) if j != i]
        q[np.ix_(sel, others)] = small[sel]
        q[sel, i] = np.sqrt(np.maximum(0.0, 1 - (small[sel] ** 2).sum(1)))
    return {
        "means": means,
        "scales": np.exp(log_scales),
        "sh_dc": (rgb - 0.5) / SH_C0,
        "alpha_byte": col & 0xFF,
        "quats": q,
        "chunk_range": np.stack([c[f"max_{a}"] - c[f"min_{a}"] for a in "xyz"], 1)[k],
    }


def _spz_payload(path: Path):
    """(version, n, SH degree, fractional bits, [section byte arrays]) of an SPZ file: v2/v3 one gzip stream
    after which a 16-byte header starts the payload; v4 a 32-byte header, a table of (compressed, plain) sizes
    and one zstd stream per section. Sections: positions 9, alpha 1, colour 3, scale 3, rotation 3 (v2) or
    4 (v3+), SH 3 per coefficient, bytes a Gaussian."""
    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        payload = gzip.decompress(raw)
        _, version, n, degree, bits = struct.unpack_from("<IIIBB", payload)
        bodies, at = [], 16
        for w in (9, 1, 3, 3, 3 if version < 3 else 4, 3 * ((degree + 1) ** 2 - 1)):
            bodies.append(np.frombuffer(payload, "u1", n * w, at).reshape(n, w))
            at += n * w
        return version, n, degree, bits, bodies
    import zstandard

    _, version, n, degree, bits, _, streams, toc = struct.unpack_from("<IIIBBBBI", raw)
    sizes = [struct.unpack_from("<QQ", raw, toc + 16 * i) for i in range(streams)]
    at, bodies = toc + 16 * streams, []
    for packed, plain in sizes:
        bodies.append(np.frombuffer(zstandard.ZstdDecompressor().decompress(raw[at : at + packed], plain), "u1"))
        at += packed
    widths = [w for w in (9, 1, 3, 3, 4, 3 * ((degree + 1) ** 2 - 1)) if w]
    bodies = [b.reshape(n, w) for b, w in zip(bodies, widths)] + ([] if degree else [np.zeros((n, 0), "u1")])
    return version, n, degree, bits, bodies


def spec_spz(path: Path) -> dict:
    """Niantic SPZ decoded from its reference loader's description, in the file's own RUB axes: positions
    24-bit signed little-endian fixed point / 2^fractional bits; alpha byte / 255; colour (b / 255 - 0.5) / 0.15;
    log-scale b / 16 - 10; rotation v2: x, y, z = b / 127.5 - 1 and w = √(1 - |xyz|²); v3+: a little-endian
    uint32 whose top 2 bits name the largest of (x, y, z, w), the others from w down to x taking 10 bits each
    (9 magnitude bits × (1/√2) / 511, then a sign bit); SH rest (b - 128) / 128, coefficient-major."""
    version, n, degree, bits, (pos, alpha, colour, scale, rot, sh) = _spz_payload(path)
    p = pos.reshape(n, 3, 3).astype(np.int64)
    fixed = p[..., 0] | (p[..., 1] << 8) | (p[..., 2] << 16)
    fixed = np.where(fixed >= 1 << 23, fixed - (1 << 24), fixed)
    if version < 3:
        xyz = rot / 127.5 - 1.0
        xyzw = np.concatenate([xyz, np.sqrt(np.maximum(0.0, 1 - (xyz**2).sum(1)))[:, None]], 1)
    else:
        word = rot.astype(np.int64) @ np.array([1, 1 << 8, 1 << 16, 1 << 24])
        largest, xyzw = word >> 30, np.zeros((n, 4))
        for i in (3, 2, 1, 0):
            take = largest != i
            mag, neg = word & 511, (word >> 9) & 1
            xyzw[take, i] = np.where(neg[take] == 1, -1.0, 1.0) * mag[take] / 511 / math.sqrt(2)
            word = np.where(take, word >> 10, word)
        xyzw[np.arange(n), largest] = np.sqrt(np.maximum(0.0, 1 - (xyzw**2).sum(1)))
    return {
        "means": fixed / float(1 << bits),
        "alpha": alpha[:, 0] / 255.0,
        "sh_dc": (colour / 255.0 - 0.5) / 0.15,
        "log_scales": scale / 16.0 - 10.0,
        "quats": np.concatenate([xyzw[:, 3:], xyzw[:, :3]], 1),  # wxyz
        "sh_rest": ((sh.astype(np.float64) - 128) / 128).reshape(n, -1, 3),
        "bits": bits,
        "version": version,
    }


def _rot(q) -> np.ndarray:  # [N, 4] wxyz -> [N, 3, 3]
    return quat_to_matrix(torch.as_tensor(np.asarray(q), dtype=torch.float64)).numpy()


def _np(gs) -> dict:
    return {k: getattr(gs, k).double().numpy() for k in ("means", "scales", "quats", "opacities", "sh")}


# ----------------------------------------------------------------------------- detection and refusals


@pytest.mark.parametrize("name", sorted(CAPTURES))
def test_each_real_capture_is_recognised_by_content(name, tmp_path):
    """The format is read from the bytes: the same file renamed to a lying suffix (a .splat called .ply, a
    compressed PLY called .dat, ...) is detected and read the same, and counts as a scene for the CLI."""
    src = DATA / name
    assert detect_format(src) == CAPTURES[name]
    liar = tmp_path / {"ply": "scene.splat", "splat": "scene.ply", "spz": "scene.bin"}.get(CAPTURES[name], "scene.dat")
    shutil.copy(src, liar)
    assert detect_format(liar) == CAPTURES[name] and is_splat_file(liar)
    a, dropped, fmt = read_gaussians(src)
    b, _, _ = read_gaussians(liar)
    assert fmt == CAPTURES[name] and dropped == 0 and len(a) > 5000
    assert all(torch.equal(getattr(a, k), getattr(b, k)) for k in ("means", "quats", "scales", "opacities", "sh"))


def _ksplat_header() -> bytes:
    """The opening of a GaussianSplats3D .ksplat (its SplatBuffer layout): a 4096-byte header, version 0.1,
    uint32 max sections 1, sections 1, max splats 5000, splats 5000, uint16 compression level 1; one 1024-byte
    section header. No real .ksplat could be obtained (README.md), so only the header is built here."""
    head = bytearray(4096 + 1024 + 5000 * 24)
    head[0:2] = bytes([0, 1])
    struct.pack_into("<4IH", head, 4, 1, 1, 5000, 5000, 1)
    return bytes(head)


REFUSED = {
    "config.ply": (b'extends = "capture"\n[sim]\ndx = 0.02\n', "TOML text"),
    "photo.ply": (b"\x89PNG\r\n\x1a\n" + bytes(200), "PNG image"),
    "mesh.ply": (
        b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        b"element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        "PLY a mesh",
    ),
    "empty.splat": (b"", "empty"),
    "noise.splat": (np.random.default_rng(7).integers(0, 256, 32 * 500, dtype=np.uint8).tobytes(), "binary data"),
    "zeros.splat": (b"0.000,0.000,0.000,0.000,0.00000\n" * 10, "text"),  # ASCII digits pass as .splat rows
    "archive.spz": (gzip.compress(b"not an spz payload at all"), "gzip-compressed data"),
    "scene.ksplat": (_ksplat_header(), "ksplat"),
}


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_what_is_not_read_is_refused_in_one_sentence(name, tmp_path):
    """TOML text, an image, a mesh PLY, an empty file, noise, text whose size fits .splat rows, gzip that is
    not SPZ and a .ksplat each get one sentence naming the file, what it looks like and the formats read."""
    content, looks = REFUSED[name]
    path = tmp_path / name
    path.write_bytes(content)
    with pytest.raises(PlyError) as err:
        read_gaussians(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: ") and looks in msg and READ in msg, msg
    assert "\n" not in msg and msg.endswith(".") and msg.count("; ") <= 2, msg
    if name == "scene.ksplat":
        assert "splat-transform" in msg and "SuperSplat" in msg
    assert is_splat_file(path) == name.endswith((".ply", ".splat", ".spz", ".ksplat"))


def test_suffix_alone_does_not_make_a_toml_file_a_scene(tmp_path):
    """A config is a scene only by suffix: `is_splat_file` is False for TOML or a missing file without a scene
    suffix, and True for a missing .spz (so the CLI says "no such .spz file", not a TOML error)."""
    cfg = tmp_path / "run.toml"
    cfg.write_text('extends = "capture"\n')
    assert not is_splat_file(cfg) and not is_splat_file(tmp_path / "nothing.dat")
    assert is_splat_file(tmp_path / "missing.spz")


# ----------------------------------------------------------------------------- gsply against the specs


@pytest.mark.parametrize("name", ["guitar.compressed.ply", "biker_5k.compressed.ply"])
def test_compressed_ply_decoding_matches_the_spec(name):
    """gsply's decoding of a real compressed PLY (through read_gaussians) equals this file's decoder of the
    format's bit layout: positions, scales, colour, opacity and rotation of every Gaussian."""
    ref, got = spec_compressed_ply(DATA / name), _np(read_gaussians(DATA / name)[0])
    assert np.allclose(got["means"], ref["means"], rtol=0, atol=1e-6 * max(1.0, np.abs(ref["means"]).max()))
    assert np.allclose(got["scales"], ref["scales"], rtol=1e-5, atol=0)
    assert np.allclose(got["sh"][:, 0], ref["sh_dc"], rtol=0, atol=1e-5)
    inner = (ref["alpha_byte"] > 0) & (ref["alpha_byte"] < 255)  # gsply writes 0 and 255 as logits ∓10
    assert np.allclose(got["opacities"][inner], ref["alpha_byte"][inner] / 255.0, rtol=0, atol=1e-6)
    assert np.allclose(got["opacities"], ref["alpha_byte"] / 255.0, rtol=0, atol=5e-5)
    assert np.allclose(_rot(got["quats"]), _rot(ref["quats"]), rtol=0, atol=1e-5)


@pytest.mark.parametrize("name", ["biker_5k.spz", "fourth_st_5k.spz"])
def test_spz_decoding_matches_the_spec_and_turns_rub_into_rdf(name):
    """gsply's decoding of a real SPZ (v4 zstd with smallest-three rotations; v2 gzip with SH degree 3) equals
    this file's decoder, once the RUB axes are turned to RDF: positions (x, -y, -z), rotations D R D with
    D = diag(1, -1, -1), the SH as the renderer's basis rotated by D (capture.transform.rotate_sh)."""
    ref, got = spec_spz(DATA / name), _np(read_gaussians(DATA / name)[0])
    assert ref["version"] == {"biker_5k.spz": 4, "fourth_st_5k.spz": 2}[name]
    assert np.allclose(got["means"], ref["means"] @ D, rtol=0, atol=1e-7)
    assert np.allclose(np.log(got["scales"]), ref["log_scales"], rtol=0, atol=1e-5)
    assert np.allclose(got["opacities"], np.clip(ref["alpha"], 1e-6, 1 - 1e-6), rtol=0, atol=1e-6)
    # gsply forms w = √(1 - |xyz|²) in float32 (v2), which keeps ~1e-5 of a small w: atol 1e-4
    assert np.allclose(_rot(got["quats"]), D @ _rot(ref["quats"]) @ D, rtol=0, atol=1e-4)
    sh_rub = np.concatenate([ref["sh_dc"][:, None], ref["sh_rest"]], 1)
    assert got["sh"].shape == sh_rub.shape == (len(got["means"]), 16 if name == "fourth_st_5k.spz" else 1, 3)
    turned = rotate_sh(torch.from_numpy(sh_rub), torch.from_numpy(D)).numpy()
    assert np.allclose(got["sh"], turned, rtol=0, atol=1e-5)


def test_spz_and_compressed_ply_of_one_capture_agree():
    """PlayCanvas ships the biker as a compressed PLY and as an SPZ (the same 5,120 Gaussians here, README.md):
    after SPZ's RUB -> RDF turn they agree within the two quantisations: positions within half an 11/10-bit
    step of the chunk plus half of SPZ's 1/4096; log-scales within half steps (SPZ clamps below -10); rotations,
    colour and opacity within a few 8-10-bit steps. Without the turn, y and z would differ in sign."""
    a, b = (_np(read_gaussians(DATA / f"biker_5k.{ext}")[0]) for ext in ("compressed.ply", "spz"))
    spec = spec_compressed_ply(DATA / "biker_5k.compressed.ply")
    step = spec["chunk_range"] / np.array([2047, 1023, 2047])
    assert (np.abs(a["means"] - b["means"]) <= 0.5 * step + 0.5 / 4096 + 1e-6).all()
    la = np.clip(np.log(a["scales"]), -10.0, 10.0)
    assert np.abs(la - np.log(b["scales"])).max() <= 0.5 / 16 + 0.01
    assert np.abs(_rot(a["quats"]) - _rot(b["quats"])).max() < 5e-3
    assert np.abs(a["opacities"] - b["opacities"]).max() <= 1.0 / 255
    assert np.abs(a["sh"] - b["sh"]).max() <= 0.5 / (0.15 * 255) + 0.5 * np.ptp(spec["sh_dc"]) / 255 + 1e-4
    assert np.abs(a["means"][:, 1:] + b["means"][:, 1:]).max() > 0.1  # the turn is not the identity


def test_spz_axis_turn_is_a_half_turn_about_x():
    """flip_yz on real SH-degree-3 Gaussians equals rotating them by D = diag(1, -1, -1): the SH through the
    renderer's basis (capture.transform.rotate_sh), the rotation as D R D; applying it twice is the identity."""
    gs = read_gaussians(DATA / "fourth_st_5k.spz")[0]
    m, q, sh = gsply_io.flip_yz(gs.means.numpy(), gs.quats.numpy(), gs.sh.numpy())
    turned = rotate_sh(gs.sh.double(), torch.from_numpy(D)).numpy()
    assert np.allclose(sh, turned, rtol=0, atol=1e-6) and np.abs(sh - gs.sh.numpy()).max() > 0.05
    assert np.allclose(_rot(q), D @ _rot(gs.quats.numpy()) @ D, atol=1e-6)
    back = gsply_io.flip_yz(m, q, sh)
    assert all(np.array_equal(x, y) for x, y in zip(back, (gs.means.numpy(), gs.quats.numpy(), gs.sh.numpy())))


# ----------------------------------------------------------------------------- writing


def _chunk_steps(means_sorted: np.ndarray, bits=(2047, 1023, 2047)) -> np.ndarray:  # [N, 3]
    """Per Gaussian, the 11-10-11-bit step of its 256-Gaussian chunk in a compressed PLY written in this order."""
    n = len(means_sorted)
    k = np.arange(n) // 256
    lo = np.stack([np.minimum.reduceat(means_sorted[:, a], np.arange(0, n, 256)) for a in range(3)], 1)
    hi = np.stack([np.maximum.reduceat(means_sorted[:, a], np.arange(0, n, 256)) for a in range(3)], 1)
    return ((hi - lo) / np.array(bits))[k]


@pytest.mark.parametrize("source", ["donut_5k.ply", "fourth_st_5k.spz"])
@pytest.mark.parametrize("fmt", ["ply", "compressed-ply", "splat", "spz"])
def test_each_format_reads_back_within_its_quantisation(source, fmt, tmp_path):
    """write_gaussians then read_gaussians: a 3DGS PLY bit for bit (from a PLY; within float32 round-off of
    exp/log from another format); a compressed PLY (rows in Morton order)
    within half a step of each chunk's bounds (8 bits of colour, 10-bit rotations, SH rest in 1/32 steps); a
    .splat with exact means and scales, 8-bit colour and opacity, DC colour only; an SPZ within 1/2^13 in
    position, 1/32 in log-scale, 8-bit colour, opacity and SH rest (±1), its SH degree kept."""
    src = read_gaussians(DATA / source)[0]
    path = write_gaussians(src, tmp_path / f"out{'.compressed.ply' if fmt == 'compressed-ply' else '.' + fmt}", fmt)
    back, dropped, got_fmt = read_gaussians(path)
    assert got_fmt == fmt and dropped == 0 and len(back) == len(src)
    a, b = _np(src), _np(back)
    if fmt == "ply":  # the file's own float32 values for a PLY source; float32 exp/log round-off otherwise
        exact = ("means", "scales", "quats", "opacities", "sh") if source.endswith(".ply") else ("means", "sh")
        assert all(np.array_equal(a[k], b[k]) for k in exact)
        assert all(np.allclose(a[k], b[k], rtol=1e-6, atol=1e-7) for k in a)
        return
    if fmt == "compressed-ply":
        a = {k: v[gsply_io.morton_order(a["means"])] for k, v in a.items()}
    rgb_a = np.clip(0.5 + SH_C0 * a["sh"][:, 0], 0, 1)
    rot_err = np.abs(_rot(a["quats"]) - _rot(b["quats"])).max()
    if fmt == "compressed-ply":
        assert (np.abs(a["means"] - b["means"]) <= 0.5 * _chunk_steps(a["means"]) + 1e-6).all()
        log_a = np.log(a["scales"])
        assert (np.abs(log_a - np.log(b["scales"])) <= 0.5 * _chunk_steps(log_a) + 1e-5).all()
        rgb = 0.5 + SH_C0 * a["sh"][:, 0]
        assert (np.abs(rgb - (0.5 + SH_C0 * b["sh"][:, 0])) <= 0.5 * _chunk_steps(rgb, (255,) * 3) + 1e-5).all()
        assert np.abs(a["sh"][:, 1:] - b["sh"][:, 1:]).max(initial=0) <= 1 / 32 + 1e-6
        assert np.abs(a["opacities"] - b["opacities"]).max() <= 0.5 / 255 + 5e-5 and rot_err < 3e-3
        assert b["sh"].shape == a["sh"].shape
    elif fmt == "splat":
        assert np.array_equal(a["means"], b["means"]) and np.array_equal(a["scales"], b["scales"])
        assert np.abs(rgb_a - (0.5 + SH_C0 * b["sh"][:, 0])).max() <= 0.5 / 255 + 1e-6
        assert np.abs(a["opacities"] - b["opacities"]).max() <= 0.5 / 255 + 1e-6
        assert b["sh"].shape[1] == 1 and rot_err < 3e-2
    else:
        assert np.abs(a["means"] - b["means"]).max() <= 0.5 / 4096 + 1e-6
        log_a = np.clip(np.log(a["scales"]), -10.0, 5.9375)
        assert np.abs(log_a - np.log(b["scales"])).max() <= 0.5 / 16 + 1e-5
        assert np.abs(np.clip(a["sh"][:, 0], -DC_MAX, DC_MAX) - b["sh"][:, 0]).max() <= 0.5 / (0.15 * 255) + 1e-5
        assert np.abs(np.clip(a["sh"][:, 1:], -1, 127 / 128) - b["sh"][:, 1:]).max(initial=0) <= 0.5 / 128 + 1e-6
        assert np.abs(a["opacities"] - b["opacities"]).max() <= 0.5 / 255 + 1e-6 and rot_err < 5e-3
        assert b["sh"].shape == a["sh"].shape


@pytest.mark.parametrize("source", ["donut_5k.ply", "luma_seal_5k.splat"])
def test_compressed_ply_is_written_in_compact_chunks(source, tmp_path):
    """A compressed PLY quantises each position within its 256-Gaussian chunk's box, so the writer orders
    the Gaussians along a Z curve: the median chunk box of the written file (read with this file's decoder)
    is under a quarter of the volume it would have in the source's own order."""
    gs = read_gaussians(DATA / source)[0]
    spec = spec_compressed_ply(write_gaussians(gs, tmp_path / "c.compressed.ply", "compressed-ply"))
    as_given = _chunk_steps(gs.means.double().numpy()) * np.array([2047, 1023, 2047])
    assert np.median(spec["chunk_range"].prod(1)) < 0.25 * np.median(as_given.prod(1))


def test_spz_far_from_the_origin_keeps_its_positions(tmp_path):
    """A capture 5,000 units from the origin does not fit SPZ's 24-bit positions at 12 fractional bits; the
    writer takes 10 bits (5000 · 2^10 < 2^23), so positions come back within half of 1/1024, not clipped."""
    gs = read_gaussians(DATA / "luma_seal_5k.splat")[0]
    far = gs.replace(means=gs.means + torch.tensor([5000.0, -5000.0, 0.0]))
    assert gsply_io.spz_fractional_bits(far.means.numpy()) == 10
    back = read_gaussians(write_gaussians(far, tmp_path / "far.spz", "spz"))[0]
    assert float((back.means - far.means).abs().max()) <= 0.5 / 1024 + 1e-3 * 0.5  # float32 at 5000 is ~5e-4


def test_unreadable_rows_are_dropped_and_counted(tmp_path):
    """As load_ply_lenient does for a 3DGS PLY: rows of a real .splat with a NaN mean, a zero or negative scale
    or a zero quaternion are dropped and counted, the others read unchanged; a compressed PLY chunk with NaN
    bounds loses its 256 Gaussians."""
    raw = bytearray((DATA / "luma_seal_5k.splat").read_bytes())
    rows = np.frombuffer(raw, np.uint8).reshape(-1, 32)
    struct.pack_into("<f", raw, 32 * 3, float("nan"))  # row 3: x
    struct.pack_into("<f", raw, 32 * 10 + 16, 0.0)  # row 10: scale z
    struct.pack_into("<f", raw, 32 * 11 + 12, -0.01)  # row 11: scale x
    raw[32 * 20 + 28 : 32 * 21] = bytes([128] * 4)  # row 20: zero quaternion
    (tmp_path / "broken.splat").write_bytes(bytes(raw))
    gs, dropped, _ = read_gaussians(tmp_path / "broken.splat")
    clean = read_gaussians(DATA / "luma_seal_5k.splat")[0]
    keep = torch.ones(len(rows), dtype=torch.bool)
    keep[[3, 10, 11, 20]] = False
    assert dropped == 4 and torch.equal(gs.means, clean.means[keep]) and torch.equal(gs.sh, clean.sh[keep])
    ply = bytearray((DATA / "biker_5k.compressed.ply").read_bytes())
    _, at = _header(bytes(ply))
    struct.pack_into("<f", ply, at + 4 * 18 * 2, float("nan"))  # chunk 2: min_x
    (tmp_path / "nan.compressed.ply").write_bytes(bytes(ply))
    assert read_gaussians(tmp_path / "nan.compressed.ply")[1] == 256


def test_cut_off_files_get_one_sentence(tmp_path):
    """A compressed PLY or an SPZ cut in the middle is refused with one sentence naming the file, not a
    numpy or zlib traceback."""
    for name in ("biker_5k.compressed.ply", "fourth_st_5k.spz", "biker_5k.spz"):
        data = (DATA / name).read_bytes()
        path = tmp_path / name
        path.write_bytes(data[: len(data) // 2])
        with pytest.raises(PlyError, match=f"^{path}: .*(cut off|could not be decoded)") as err:
            read_gaussians(path)
        assert "\n" not in str(err.value)


def test_exported_ply_is_still_read_by_load_ply(tmp_path):
    """write_gaussians(fmt="ply") is save_ply: the file is a 3DGS PLY any trainer's loader reads."""
    gs = read_gaussians(DATA / "biker_5k.spz")[0]
    back = load_ply(write_gaussians(gs, tmp_path / "b.ply"))
    assert torch.equal(back.means, gs.means) and torch.allclose(back.scales, gs.scales, rtol=1e-6)


# ----------------------------------------------------------------------------- the command line


@pytest.mark.slow
def test_render_sim_on_an_spz_capture_exports_spz_frames_in_the_scene_frame(tmp_path):
    """`render-sim capture.spz --export-ply 2 --export-format spz` simulates a real SPZ capture and writes
    frames 0 and 2 as .spz files that read back; frame 0's Gaussians sit where the capture's own Gaussians
    are (the scene's coordinates, not the simulation's), within SPZ's 1/4096 step."""
    from scipy.spatial import cKDTree

    src = DATA / "biker_5k.spz"
    out = tmp_path / "run"
    res = subprocess.run(
        [sys.executable, "-m", "fracture_gs.cli", "render-sim", str(src), "--frames", "2", "--variants", "baseline"]
        + ["--resolution", "64x48", "--device", "cpu", "--out", str(out), "--export-ply", "2"]
        + ["--export-format", "spz"],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert res.returncode == 0, res.stderr[-3000:]
    files = sorted(p.name for p in (out / "ply" / "baseline").iterdir())
    assert files == ["frame_0000.spz", "frame_0002.spz"]
    frame0, dropped, fmt = read_gaussians(out / "ply" / "baseline" / "frame_0000.spz")
    assert fmt == "spz" and dropped == 0 and 4500 < len(frame0) <= 5120
    scene = read_gaussians(src)[0].means.double().numpy()
    dist, _ = cKDTree(scene).query(frame0.means.double().numpy())
    assert dist.max() < 2e-3, dist.max()
    assert len(read_gaussians(out / "ply" / "baseline" / "frame_0002.spz")[0]) == len(frame0)


@pytest.mark.slow
def test_init_reads_a_splat_whose_suffix_lies(tmp_path, capsys):
    """`fracture-gs init` takes a real .splat saved as `seal.bin`: the content decides, the starter TOML names
    the file, and loading that TOML gives the same scene."""
    from fracture_gs import cli
    from fracture_gs.io.config import load_config

    liar = tmp_path / "seal.bin"
    shutil.copy(DATA / "luma_seal_5k.splat", liar)
    code = cli.main(["init", str(liar), "--out", str(tmp_path / "seal.toml"), "--load", "drop"])
    assert code == 0, capsys.readouterr().err
    text = (tmp_path / "seal.toml").read_text()
    assert "seal.bin" in text
    assert load_config(tmp_path / "seal.toml").scene == str(liar.resolve())


def test_capture_without_fit_reads_any_format_as_written(tmp_path):
    """`capture.fit = false` takes the file's coordinates as they are, for any format: the resolved Gaussians
    of a .splat are the file's, and its rows with broken values are dropped and reported, not fatal."""
    from fracture_gs.capture.scene import resolve
    from fracture_gs.io.config import load_config

    raw = bytearray((DATA / "luma_seal_5k.splat").read_bytes())
    struct.pack_into("<f", raw, 32 * 5 + 4, float("inf"))  # row 5: y
    (tmp_path / "seal.splat").write_bytes(bytes(raw))
    cfg = load_config(tmp_path / "seal.splat")
    cfg.capture.fit, cfg.fill_interior = False, False
    cap = resolve(cfg)
    ref = read_gaussians(DATA / "luma_seal_5k.splat")[0]
    keep = torch.arange(len(ref)) != 5
    assert cap.transform is None and torch.equal(cap.gaussians.means, ref.means[keep])
    assert any("dropped 1 unreadable" in note for note in cap.notes)
