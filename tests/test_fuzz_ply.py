"""Property: whatever PLY file a user hands over, `load_ply` and `load_ply_lenient` either load it with
finite, usable Gaussians or raise `PlyError` with a message — never another exception — and they agree
with an independent statement of what a valid 3DGS PLY is (`expected`): a valid file is never refused,
an invalid one is never accepted (no silent acceptance), and the lenient loader drops exactly the bad
rows. Files: all three encodings (ascii, binary little/big endian), SH degree 0–3, normals or not, extra
properties of every PLY scalar type, then mutations: deleted, retyped or renumbered properties,
non-finite or extreme values, zero quaternions, bad fgs_label/fgs_interior, truncation, a corrupt
header, an empty vertex element."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from fuzzutil import Tally, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st
from plyfile import PlyData, PlyElement

from fracture_gs.errors import PlyError
from fracture_gs.io.ply import load_ply, load_ply_lenient

pytestmark = pytest.mark.usefixtures("one_thread")

REQUIRED = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2"]
REQUIRED += ["rot_0", "rot_1", "rot_2", "rot_3"]
REST = [0, 9, 24, 45]
SCALAR_TYPES = ["i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8"]
SIGMA = (1e-18, 1e18)
MUTATIONS = [
    "none",
    "nonfinite",
    "extreme_scale",
    "zero_quat",
    "delete_required",
    "retype",
    "rest_gap",
    "bad_label",
    "bad_interior",
    "truncate",
    "header",
    "empty",
    "huge_values",
]


def expected(v: np.ndarray, truncated: bool) -> tuple[bool, int]:
    """(valid for load_ply, rows the lenient loader keeps or −1 when it must refuse the file), from the
    format's rules, not the loader's code: ≥ 1 vertex; the 14 required properties; f_rest_* numbered
    0..M−1 with M ∈ {0, 9, 24, 45}; every used value finite as float32; σ = exp(log-scale) within
    [1e-18, 1e18]; quaternion ≠ 0; fgs_label a non-negative int32 integer; fgs_interior 0 or 1. The
    lenient loader keeps the rows that pass all row rules (and have finite extra float values too)."""
    names = list(v.dtype.names or ())
    if truncated or len(v) == 0 or any(r not in names for r in REQUIRED):
        return False, -1
    rest = sorted(int(n[7:]) for n in names if n.startswith("f_rest_"))
    if rest != list(range(len(rest))) or len(rest) not in REST:
        return False, -1
    used = REQUIRED + [f"f_rest_{i}" for i in rest]
    with np.errstate(over="ignore", invalid="ignore"):
        f32 = {n: v[n].astype(np.float32).astype(np.float64) for n in names}
        row_ok = np.all([np.isfinite(f32[n]) for n in used], axis=0)
        for i in range(3):
            sigma = np.exp(f32[f"scale_{i}"]).astype(np.float32).astype(np.float64)
            row_ok &= np.isfinite(sigma) & (sigma >= SIGMA[0]) & (sigma <= SIGMA[1])
        quat = np.stack([f32[f"rot_{i}"] for i in range(4)], 1)
        row_ok &= np.nan_to_num(np.linalg.norm(quat, axis=1)) > 0
        if "fgs_label" in names:
            lab = v["fgs_label"].astype(np.float64)
            row_ok &= np.isfinite(lab) & (lab == np.round(lab)) & (lab >= 0) & (lab <= 2**31 - 1)
        if "fgs_interior" in names:
            row_ok &= (v["fgs_interior"] == 0) | (v["fgs_interior"] == 1)
        lenient = row_ok.copy()
        for n in names:
            if v[n].dtype.kind == "f":
                lenient &= np.isfinite(f32[n])
    return bool(row_ok.all()), int(lenient.sum())


@st.composite
def ply_case(draw):
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(1, 12))
    degree = draw(st.sampled_from([0, 1, 2, 3]))
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if draw(st.booleans()) else [])
    names += ["f_dc_0", "f_dc_1", "f_dc_2"] + [f"f_rest_{i}" for i in range(REST[degree])]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    fields = [(nm, "f4") for nm in names]
    for i in range(draw(st.integers(0, 3))):
        fields.append((f"extra_{i}", draw(st.sampled_from(SCALAR_TYPES))))
    ours = draw(st.sampled_from([(), ("fgs_label",), ("fgs_interior",), ("fgs_label", "fgs_interior")]))
    fields += [(o, "i4" if o == "fgs_label" else "u1") for o in ours]
    mutation = draw(st.sampled_from(MUTATIONS))
    if draw(st.booleans()):
        rng.shuffle(fields)
    if mutation == "retype":
        k = draw(st.integers(0, len(fields) - 1))
        fields[k] = (fields[k][0], draw(st.sampled_from(SCALAR_TYPES)))
    if mutation == "delete_required":
        gone = draw(st.sampled_from(REQUIRED))
        fields = [f for f in fields if f[0] != gone]
    if mutation == "rest_gap" and degree > 0:
        gone = f"f_rest_{draw(st.integers(0, REST[degree] - 1))}"
        fields = [f for f in fields if f[0] != gone]
    v = np.zeros(0 if mutation == "empty" else n, dtype=fields)
    for nm, kind in fields:
        if kind.startswith("f"):
            v[nm] = rng.normal(0, 1, len(v)) * (3.0 if nm in ("x", "y", "z") else 1.0)
        else:
            info = np.iinfo(np.dtype(kind))
            v[nm] = rng.integers(max(info.min, -50), min(info.max, 50), len(v), endpoint=True)
    for i in range(3):
        if f"scale_{i}" in v.dtype.names and v.dtype[f"scale_{i}"].kind == "f":
            v[f"scale_{i}"] = rng.uniform(-9, 3, len(v))
    for o in ours:
        v[o] = rng.integers(0, 2 if o == "fgs_interior" else 5, len(v))
    if "rot_0" in v.dtype.names:
        v["rot_0"] = np.where(v["rot_0"] == 0, 1, v["rot_0"])
    row = draw(st.integers(0, max(0, len(v) - 1)))
    floats = [nm for nm, kind in fields if kind.startswith("f")]
    if len(v) and mutation == "nonfinite" and floats:
        v[draw(st.sampled_from(floats))][row] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    if len(v) and mutation == "extreme_scale":
        target = draw(st.sampled_from(["scale_0", "scale_1", "scale_2"]))
        if target in v.dtype.names:
            v[target][row] = draw(st.sampled_from([88.0, 42.0, -42.0, -100.0, 41.0, -41.0, 1e4]))
    if len(v) and mutation == "zero_quat":
        for i in range(4):
            if f"rot_{i}" in v.dtype.names:
                v[f"rot_{i}"][row] = 0
    if len(v) and mutation == "bad_label" and "fgs_label" in v.dtype.names:
        v["fgs_label"][row] = draw(st.sampled_from([-1, -(2**31)]))
    if len(v) and mutation == "bad_interior" and "fgs_interior" in v.dtype.names:
        v["fgs_interior"][row] = draw(st.sampled_from([2, 255]))
    if len(v) and mutation == "huge_values":
        target = draw(st.sampled_from([nm for nm, kind in fields if kind == "f8"] or ["x"]))
        if target in v.dtype.names and v.dtype[target].kind == "f":
            with np.errstate(over="ignore"):
                v[target][row] = draw(st.sampled_from([1e30, -1e30, 3e38, 1e39, 1e300]))
    encoding = draw(st.sampled_from(["ascii", "<", ">"]))
    cut = draw(st.integers(1, 40)) if mutation == "truncate" else 0
    flip = draw(st.integers(0, 10_000)) if mutation == "header" else None
    return v, encoding, mutation, cut, flip


def write_case(path, v, encoding, cut, flip) -> bool:
    """Write the file; returns whether it was damaged beyond the rules (truncated or header flipped)."""
    el = PlyElement.describe(v, "vertex")
    PlyData([el], text=encoding == "ascii", byte_order=encoding if encoding != "ascii" else "=").write(str(path))
    data = path.read_bytes()
    if cut:
        body = data.index(b"end_header\n") + len(b"end_header\n")
        if encoding == "ascii":
            lines = data[body:].splitlines(keepends=True)
            keep = max(0, len(lines) - 1 - cut % max(1, len(lines)))
            data = data[:body] + b"".join(lines[:keep])
        else:
            data = data[: max(body, len(data) - cut)]
        path.write_bytes(data)
        return len(v) > 0
    if flip is not None:
        header_end = data.index(b"end_header")
        pos = flip % header_end
        path.write_bytes(data[:pos] + bytes([data[pos] ^ 0x5A]) + data[pos + 1 :])
        return True
    return False


def assert_usable(gs) -> None:
    """Never NaN in an output: every tensor of a loaded scene is finite and within its meaning."""
    assert torch.isfinite(gs.means).all() and torch.isfinite(gs.sh).all()
    assert torch.isfinite(gs.scales**2).all() and (gs.scales**2 > 0).all()
    torch.testing.assert_close(gs.quats.norm(dim=1), torch.ones(len(gs)), atol=1e-5, rtol=0)
    assert ((gs.opacities >= 0) & (gs.opacities <= 1)).all()


@pytest.mark.slow
def test_fuzz_ply(tmp_path_factory, capsys):
    tally = Tally("PLY")
    folder = tmp_path_factory.mktemp("fuzz_ply")

    @fuzz_settings(1000)
    @given(ply_case())
    def prop(case):
        v, encoding, mutation, cut, flip = case
        path = folder / "case.ply"
        damaged = write_case(path, v, encoding, cut, flip)
        valid, lenient_rows = expected(v, damaged and flip is None)
        category = f"{mutation} ({'ascii' if encoding == 'ascii' else 'binary ' + encoding})"
        try:
            gs = load_ply(path)
        except PlyError as err:
            assert str(err).startswith(str(path)), err  # the message names the file
            if valid and flip is None:
                tally.add(category, "false rejection")
                raise AssertionError(f"a valid PLY was refused: {err}") from None
            tally.add(category, "our error")
        except Exception:
            tally.add(category, "traceback")
            raise
        else:
            if not valid and flip is None:
                tally.add(category, "silent acceptance")
                raise AssertionError(f"an invalid PLY ({mutation}) loaded")
            assert_usable(gs)
            assert flip is not None or len(gs) == len(v)
            tally.add(category, "clean load")
        if flip is None and not damaged:
            try:
                lenient, dropped = load_ply_lenient(path)
            except PlyError:
                assert lenient_rows <= 0, "the lenient loader refused a file with usable rows"
            else:
                assert len(lenient) == lenient_rows and dropped == len(v) - lenient_rows
                assert_usable(lenient)

    prop()
    tally.report(capsys)
    assert tally.total() >= 1000 and tally.total("traceback") == 0 and tally.total("silent acceptance") == 0
    assert tally.total("our error") > 50 and tally.total("clean load") > 50  # both sides were exercised
