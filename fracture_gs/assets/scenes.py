"""The six built-in scenes (metres, z up, inside the unit cube). Configs rely on these exact
geometries and labels:

bread       loaf x∈[0.25,0.75], y∈[0.39,0.61], z∈[0.15,0.33]: rounded-rectangle footprint (corner
            radius 0.06), flat bottom z=0.15, domed top (ellipsoid, peak 0.33 at the centre).
            0 = crust (outer max(0.012, h) and every drawn Gaussian), 1 = crumb.
ficus       0 = terracotta pot, truncated cone about (0.5,0.5), z∈[0.05,0.17], radius 0.07→0.09
            (rim 0.094 over z∈[0.155,0.17]); 1 = soil filling its cavity (r < R(z)-0.012,
            z > 0.062), top disc flush at z=0.17; 2 = wood: trunk from z=0.17 (rounded foot down
            to 0.154 in the soil) to (0.53,0.51,0.55), radius 0.016→0.011, slightly bent, and 4
            branches (radius 0.008→0.005) from z≈0.40–0.55 to tips 0.12 from the axis at
            z∈[0.57,0.64]; 3 = leaves: ellipsoid clusters around the tips and the trunk top,
            canopy x,y∈[≈0.33,≈0.68], z∈[≈0.51,≈0.69] (3 wins over 0/1, 2 wins over 3).
recontact   0 = block A x∈[0.30,0.46], 1 = block B x∈[0.50,0.58]; both y,z∈[0.42,0.58].
beam        0 = box x∈[0.2,0.8], y∈[0.45,0.55], z∈[0.30,0.36] (wood).
plane_drop  capsule of total length 0.3 (segment x∈[0.40,0.60] of radius 0.05 in its rest frame)
            centred at (0.5,0.5,0.4), rotated +15° about y (its +x end lower: the rest-frame point
            (x,y,z) maps to c + R_y(15°)(p - c)); 0 = rest-frame x < 0.5, 1 = x ≥ 0.5.
plate_drop  a glazed plate: disc of radius 0.14 and thickness 0.03 centred at (0.5,0.5,0.30), tilted
            6° about y (+x edge lower); one label 0 (ceramic).
"""

from __future__ import annotations

import math

import torch

from . import shapes as S
from .builder import SceneSpec

# ----------------------------------------------------------------------------- colour helpers


def _rgb(c, m: int) -> torch.Tensor:  # -> [m, 3]
    return torch.tensor(c, dtype=torch.float32).expand(m, 3).clone()


def _mix(a: torch.Tensor, b: torch.Tensor, t: torch.Tensor) -> torch.Tensor:  # [M,3],[M,3],[M]
    return a + (b - a) * t.clamp(0, 1)[:, None]


def _vary(rgb: torch.Tensor, p: torch.Tensor, gen, freq: float, low: float, grain: float):
    """rgb × (1 + low·smooth noise + grain·per-particle noise): large blotches plus speckle."""
    f = 1 + low * S.smooth_noise(p, gen, freq) + grain * torch.randn(len(p), generator=gen)
    return rgb * f[:, None]


def _by_label(labels: torch.Tensor, parts: dict) -> torch.Tensor:  # [M] -> [M, 3]
    """Pick the colour array of each particle's label from {label: rgb [M, 3]}."""
    out = torch.zeros(len(labels), 3)
    for lab, rgb in parts.items():  # a handful of labels, not particles
        sel = labels == lab
        out[sel] = rgb[sel]
    return out


# ----------------------------------------------------------------------------- bread

BREAD_CRUST = 0.012


def _bread_sdf(p):
    side = S.rounded_rect_xy(p, (0.5, 0.5), (0.25, 0.11), 0.06)
    dome = S.ellipsoid(p, (0.5, 0.5, 0.15), (0.30, 0.14, 0.18))
    return S.smooth_max(S.smooth_max(side, dome, 0.03), 0.15 - p[:, 2], 0.008)


def _bread_labels(p, d, h):
    return torch.where(d > -max(BREAD_CRUST, h), 0, 1)


def _bread_colors(p, labels, normals, surface, gen):
    m, z = len(p), p[:, 2]
    crust = _mix(_rgb((0.80, 0.54, 0.25), m), _rgb((0.50, 0.28, 0.11), m), (z - 0.21) / 0.11)
    crust = _mix(crust, _rgb((0.84, 0.70, 0.48), m), (0.165 - z) / 0.015)  # floured bottom
    crust = _vary(crust, p, gen, 20.0, 0.07, 0.04)
    crumb = _vary(_rgb((0.95, 0.89, 0.73), m), p, gen, 60.0, 0.03, 0.03)
    return _by_label(labels, {0: crust, 1: crumb})


BREAD = SceneSpec(
    "bread", (0.25, 0.39, 0.15), (0.75, 0.61, 0.33), 182_959, _bread_sdf, _bread_labels, _bread_colors, view_std=0.04
)

# ----------------------------------------------------------------------------- ficus

POT = dict(z0=0.05, z1=0.17, r0=0.07, r1=0.09, wall=0.012)
_AXIS = (0.5, 0.5)


def _trunk_points():
    """Polyline of the slightly bent trunk: quadratic Bézier (0.5,0.5,0.17)→(0.53,0.51,0.55)."""
    t = torch.linspace(0, 1, 6)[:, None]
    a, c, b = (torch.tensor(v) for v in ([0.5, 0.5, 0.17], [0.485, 0.497, 0.36], [0.53, 0.51, 0.55]))
    return ((1 - t) ** 2 * a + 2 * t * (1 - t) * c + t**2 * b).tolist()


def _branches():
    """(base, tip) of the 4 branches: bases on the upper trunk, tips 0.12 from the axis."""
    trunk = _trunk_points()
    out = []
    for i, (az, tip_z) in enumerate([(20, 0.60), (115, 0.64), (205, 0.57), (295, 0.62)]):
        base = trunk[3 + i % 3]
        a = math.radians(az)
        out.append((base, [0.5 + 0.12 * math.cos(a), 0.5 + 0.12 * math.sin(a), tip_z]))
    return out


def _leaf_blobs():
    """Ellipsoids (centre, radii) of the leaf clusters, fixed (independent of the scene seed)."""
    g = torch.Generator().manual_seed(7)
    tips = [tip for _, tip in _branches()] + [_trunk_points()[-1][:2] + [0.61]]
    blobs = []
    for tip in tips:
        for k in range(4):
            off = (torch.rand(3, generator=g) * 2 - 1) * torch.tensor([0.03, 0.03, 0.02])
            off[2] -= 0.012 * k  # droop
            r = 0.036 + 0.012 * torch.rand(3, generator=g)
            blobs.append(((torch.tensor(tip) + off).tolist(), (r * torch.tensor([1, 1, 0.8])).tolist()))
    return blobs


_TRUNK, _BRANCHES, _BLOBS = _trunk_points(), _branches(), _leaf_blobs()


def _pot_sdf(p):
    body = S.capped_cone_z(p, _AXIS, POT["z0"], POT["z1"], POT["r0"], POT["r1"])
    return torch.minimum(body, S.capped_cone_z(p, _AXIS, 0.155, POT["z1"], 0.094, 0.094))


def _soil_sdf(p):
    w = POT["wall"]
    return S.capped_cone_z(
        p,
        _AXIS,
        POT["z0"] + w,
        POT["z1"] + 0.01,
        POT["r0"] - w,
        POT["r1"] - w + (POT["r1"] - POT["r0"]) * 0.01 / (POT["z1"] - POT["z0"]),
    )


def _wood_sdf(p):
    n = len(_TRUNK) - 1
    ds = [
        S.capsule(p, _TRUNK[i], _TRUNK[i + 1], (0.016 - 0.005 * i / n, 0.016 - 0.005 * (i + 1) / n)) for i in range(n)
    ]
    ds += [S.capsule(p, a, b, (0.008, 0.005)) for a, b in _BRANCHES]
    return S.union(*ds)


def _leaf_sdf(p):
    return S.union(*[S.ellipsoid(p, c, r) for c, r in _BLOBS])


def _ficus_sdf(p):
    return torch.minimum(torch.minimum(_pot_sdf(p), _wood_sdf(p)), _leaf_sdf(p))


def _ficus_labels(p, d, h):
    lab = torch.zeros(len(p), dtype=torch.int32)
    lab[_soil_sdf(p) < 0] = 1
    lab[_leaf_sdf(p) < 0] = 3
    lab[_wood_sdf(p) < 0] = 2
    return lab


def _ficus_colors(p, labels, normals, surface, gen):
    m, z = len(p), p[:, 2]
    pot = _mix(_rgb((0.62, 0.30, 0.18), m), _rgb((0.78, 0.42, 0.26), m), (z - 0.05) / 0.12)
    pot = _vary(pot, p, gen, 25.0, 0.06, 0.04)
    soil = _vary(_rgb((0.24, 0.16, 0.10), m), p, gen, 80.0, 0.10, 0.15)
    wood = _vary(_rgb((0.42, 0.30, 0.19), m), p, gen, 40.0, 0.08, 0.06)
    shade = 0.5 + 0.25 * S.smooth_noise(p, gen, 15.0) + 0.2 * torch.randn(m, generator=gen) + 1.5 * (z - 0.6)
    leaf = _mix(_rgb((0.09, 0.28, 0.07), m), _rgb((0.40, 0.62, 0.20), m), shade)
    return _by_label(labels, {0: pot, 1: soil, 2: wood, 3: leaf})


FICUS = SceneSpec(
    "ficus",
    (0.30, 0.30, 0.05),
    (0.70, 0.70, 0.75),
    171_553,
    _ficus_sdf,
    _ficus_labels,
    _ficus_colors,
    foliage=(3,),
    view_std=0.03,
)

# ----------------------------------------------------------------------------- recontact blocks

BLOCK_A = ((0.30, 0.42, 0.42), (0.46, 0.58, 0.58))
BLOCK_B = ((0.50, 0.42, 0.42), (0.58, 0.58, 0.58))


def _recontact_sdf(p):
    return torch.minimum(S.box(p, *BLOCK_A), S.box(p, *BLOCK_B))


def _recontact_colors(p, labels, normals, surface, gen):
    m = len(p)
    a = _vary(_rgb((0.82, 0.24, 0.18), m), p, gen, 15.0, 0.05, 0.03)
    b = _vary(_rgb((0.18, 0.40, 0.80), m), p, gen, 15.0, 0.05, 0.03)
    return _by_label(labels, {0: a, 1: b})


RECONTACT = SceneSpec(
    "recontact",
    BLOCK_A[0],
    BLOCK_B[1],
    170_000,
    _recontact_sdf,
    lambda p, d, h: torch.where(p[:, 0] < 0.48, 0, 1),
    _recontact_colors,
)

# ----------------------------------------------------------------------------- beam

BEAM_BOX = ((0.2, 0.45, 0.30), (0.8, 0.55, 0.36))


def _beam_colors(p, labels, normals, surface, gen):
    m = len(p)
    r = torch.linalg.vector_norm(p[:, 1:] - torch.tensor([0.47, 0.12]), dim=-1)  # growth rings
    rings = torch.sin(2 * math.pi * (90 * r + 0.6 * S.smooth_noise(p * torch.tensor([0.15, 1, 1]), gen, 8.0)))
    wood = _mix(_rgb((0.72, 0.52, 0.30), m), _rgb((0.52, 0.34, 0.18), m), 0.5 + 0.5 * rings)
    return _vary(wood, p, gen, 6.0, 0.05, 0.03)


BEAM = SceneSpec(
    "beam",
    *BEAM_BOX,
    170_000,
    lambda p: S.box(p, *BEAM_BOX),
    lambda p, d, h: torch.zeros(len(p), dtype=torch.int32),
    _beam_colors,
    view_std=0.02,
)

# ----------------------------------------------------------------------------- plane drop

DROP_CENTER, DROP_TILT = (0.5, 0.5, 0.4), 15.0
DROP_HALF, DROP_RADIUS = 0.10, 0.05  # segment half-length and radius: total length 0.3


def _drop_rest(p):
    """World points mapped back to the bar's rest frame."""
    return S.rotate_y(p, DROP_CENTER, -DROP_TILT)


def _drop_sdf(p):
    cx, cy, cz = DROP_CENTER
    return S.capsule(_drop_rest(p), (cx - DROP_HALF, cy, cz), (cx + DROP_HALF, cy, cz), DROP_RADIUS)


def _drop_colors(p, labels, normals, surface, gen):
    m = len(p)
    granite = _vary(_rgb((0.56, 0.56, 0.54), m), p, gen, 30.0, 0.05, 0.10)
    sandstone = _vary(_rgb((0.74, 0.63, 0.46), m), p, gen, 12.0, 0.08, 0.04)
    return _by_label(labels, {0: granite, 1: sandstone})


def _drop_box():
    t = math.radians(DROP_TILT)
    ex = DROP_HALF * math.cos(t) + DROP_RADIUS
    ez = DROP_HALF * math.sin(t) + DROP_RADIUS
    c = DROP_CENTER
    return (c[0] - ex, c[1] - DROP_RADIUS, c[2] - ez), (c[0] + ex, c[1] + DROP_RADIUS, c[2] + ez)


PLANE_DROP = SceneSpec(
    "plane_drop",
    *_drop_box(),
    170_000,
    _drop_sdf,
    lambda p, d, h: torch.where(_drop_rest(p)[:, 0] < DROP_CENTER[0], 0, 1),
    _drop_colors,
)

# ----------------------------------------------------------------------------- plate drop

PLATE_CENTER, PLATE_RADIUS, PLATE_THICK, PLATE_TILT = (0.5, 0.5, 0.30), 0.14, 0.03, 6.0


def _plate_sdf(p):
    cx, cy, cz = PLATE_CENTER
    q = S.rotate_y(p, PLATE_CENTER, -PLATE_TILT)
    return S.capped_cone_z(q, (cx, cy), cz - PLATE_THICK / 2, cz + PLATE_THICK / 2, PLATE_RADIUS, PLATE_RADIUS)


def _plate_colors(p, labels, normals, surface, gen):
    m = len(p)
    r = torch.linalg.vector_norm(p[:, :2] - torch.tensor(PLATE_CENTER[:2]), dim=-1)
    glaze = _vary(_rgb((0.93, 0.92, 0.88), m), p, gen, 10.0, 0.02, 0.02)
    rim = (r > PLATE_RADIUS - 0.025) & (r < PLATE_RADIUS - 0.012)
    ang = torch.atan2(p[:, 1] - PLATE_CENTER[1], p[:, 0] - PLATE_CENTER[0])
    motif = (r > 0.04) & (r < 0.06) & (torch.sin(8 * ang) > 0.3)
    return torch.where((rim | motif)[:, None], _rgb((0.16, 0.30, 0.62), m), glaze)


def _plate_box():
    t = math.radians(PLATE_TILT)
    ex = PLATE_RADIUS * math.cos(t) + PLATE_THICK / 2 * math.sin(t)
    ez = PLATE_RADIUS * math.sin(t) + PLATE_THICK / 2 * math.cos(t)
    c = PLATE_CENTER
    return (c[0] - ex, c[1] - PLATE_RADIUS, c[2] - ez), (c[0] + ex, c[1] + PLATE_RADIUS, c[2] + ez)


PLATE = SceneSpec(
    "plate_drop",
    *_plate_box(),
    170_000,
    _plate_sdf,
    lambda p, d, h: torch.zeros(len(p), dtype=torch.int32),
    _plate_colors,
    view_std=0.05,
)

SCENES = {s.name: s for s in (BREAD, FICUS, RECONTACT, BEAM, PLANE_DROP, PLATE)}
