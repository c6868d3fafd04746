"""Boundary operators: plane colliders, moving cuboids, moving spheres, domain walls (grid side) and timed
particle regions (impulse / velocity override).

Grid-side operators are `@wp.func`s applied per field after the contact projection (Algorithm 1);
`Boundaries` packs the config's boundary list into device arrays once.
"""

from __future__ import annotations

import torch
import warp as wp

from ...config import CuboidBoundary, ParticleRegion, PlaneBoundary, SphereBoundary
from ...errors import SimulationError
from ...runtime import ensure_warp, launch
from ..clock import Clock

wp.set_module_options({"enable_backward": False})  # forward-only kernels compile in half the time

PLANE_MODE_IDS = {"sticky": 0, "slip": 1, "friction": 2}


@wp.func
def plane_velocity(v: wp.vec3, xi: wp.vec3, point: wp.vec3, n: wp.vec3, mode: int, mu: float):
    """Collider on nodes behind the plane ((x_i − point)·n < 0): sticky v = 0; slip removes the
    approaching normal part; friction additionally shrinks |v_t| by μ|v_n| (Coulomb)."""
    if wp.dot(xi - point, n) >= 0.0:
        return v
    if mode == 0:
        return wp.vec3(0.0)
    vn = wp.dot(v, n)
    if vn >= 0.0:
        return v
    vt = v - vn * n
    if mode == 1:
        return vt
    speed = wp.length(vt)
    if speed <= 0.0:
        return vt
    return vt * wp.max(0.0, 1.0 + mu * vn / speed)


@wp.func
def cuboid_velocity(
    v: wp.vec3, xi: wp.vec3, t: float, lower: wp.vec3, upper: wp.vec3, vb: wp.vec3, tw: wp.vec2, push: wp.vec3
):
    """Moving cuboid (corners at time tw[0], velocity vb, active for tw[0] ≤ t ≤ tw[1]) on a node inside
    it: sticky (push = 0) the node takes its velocity; a pusher (push a unit direction) removes the part
    of the node's velocity relative to the box that runs against push, v ← v − min(0, (v − vb)·push) push."""
    if t < tw[0] or t > tw[1]:
        return v
    shift = vb * (t - tw[0])
    lo = lower + shift
    hi = upper + shift
    if xi[0] < lo[0] or xi[0] > hi[0] or xi[1] < lo[1] or xi[1] > hi[1] or xi[2] < lo[2] or xi[2] > hi[2]:
        return v
    if wp.dot(push, push) == 0.0:
        return vb
    vn = wp.dot(v - vb, push)
    if vn >= 0.0:
        return v
    return v - vn * push


@wp.func
def sphere_velocity(v: wp.vec3, xi: wp.vec3, t: float, start: wp.vec3, radius: float, vs: wp.vec3, tw: wp.vec2):
    """Kinematic rigid sphere (centre `start` at time tw[0], velocity vs, active for tw[0] ≤ t ≤ tw[1]) on
    a node at xi: inside it, the part of the node's velocity relative to the sphere that points into it
    is removed, v ← v − min(0, v_rel·n) n with v_rel = v − vs and n the outward normal at xi (the sphere
    pushes, it never pulls or glues). At the centre itself n is taken along vs (its leading direction)."""
    if t < tw[0] or t > tw[1]:
        return v
    d = xi - (start + vs * (t - tw[0]))
    r = wp.length(d)
    if r >= radius:
        return v
    n = wp.vec3(0.0, 0.0, 1.0)
    if r > 0.0:
        n = d / r
    elif wp.length(vs) > 0.0:
        n = wp.normalize(vs)
    vn = wp.dot(v - vs, n)
    if vn >= 0.0:
        return v
    return v - vn * n


@wp.func
def wall_velocity(v: wp.vec3, node: wp.vec3i, shape: wp.vec3i, cells: int):
    """Domain walls: within `cells` nodes of the grid edge, outward motion is removed (slip)."""
    out = v
    for a in range(3):
        if node[a] < cells and out[a] < 0.0:
            out[a] = 0.0
        if node[a] >= shape[a] - cells and out[a] > 0.0:
            out[a] = 0.0
    return out


@wp.struct
class Colliders:
    """Every grid-side boundary operator's data (built once by `Boundaries`)."""

    plane_point: wp.array(dtype=wp.vec3)
    plane_normal: wp.array(dtype=wp.vec3)
    plane_mode: wp.array(dtype=wp.int32)
    plane_mu: wp.array(dtype=float)
    box_lower: wp.array(dtype=wp.vec3)
    box_upper: wp.array(dtype=wp.vec3)
    box_velocity: wp.array(dtype=wp.vec3)
    box_time: wp.array(dtype=wp.vec2)
    box_push: wp.array(dtype=wp.vec3)
    sphere_centre: wp.array(dtype=wp.vec3)
    sphere_radius: wp.array(dtype=float)
    sphere_velocity: wp.array(dtype=wp.vec3)
    sphere_time: wp.array(dtype=wp.vec2)
    shape: wp.vec3i
    wall_cells: int


@wp.func
def apply_boundaries(v: wp.vec3, node: wp.vec3i, xi: wp.vec3, t: float, c: Colliders):
    """All grid-side boundary operators for one node's field velocity, in a fixed order:
    moving cuboids, moving spheres, plane colliders, domain walls. Its loops run over the arrays' lengths
    (dynamic loops), which Warp does not differentiate: the differentiable kernels use
    `diff.kernels.apply_boundaries_unrolled` (the same operators in the same order)."""
    out = v
    for b in range(c.box_lower.shape[0]):
        out = cuboid_velocity(
            out, xi, t, c.box_lower[b], c.box_upper[b], c.box_velocity[b], c.box_time[b], c.box_push[b]
        )
    for b in range(c.sphere_radius.shape[0]):
        vs = c.sphere_velocity[b]
        out = sphere_velocity(out, xi, t, c.sphere_centre[b], c.sphere_radius[b], vs, c.sphere_time[b])
    for b in range(c.plane_point.shape[0]):
        out = plane_velocity(out, xi, c.plane_point[b], c.plane_normal[b], c.plane_mode[b], c.plane_mu[b])
    return wall_velocity(out, node, c.shape, c.wall_cells)


@wp.kernel
def apply_particle_region(
    x: wp.array(dtype=wp.vec3),  # [N]
    v: wp.array(dtype=wp.vec3),  # [N]
    lower: wp.vec3,
    upper: wp.vec3,
    kind: int,  # 0 impulse: v += dv; 1 override: v = value
    r: int,  # region index: its activity and value this substep come from the clock's table
    clock: Clock,
):
    """Timed particle region r on the particles inside [lower, upper], if active this substep."""
    i = clock.step[0] * clock.regions + r
    if clock.region_on[i] == 0:
        return
    value = clock.region_value[i]
    p = wp.tid()
    xp = x[p]
    if (
        xp[0] >= lower[0]
        and xp[0] <= upper[0]
        and xp[1] >= lower[1]
        and xp[1] <= upper[1]
        and xp[2] >= lower[2]
        and xp[2] <= upper[2]
    ):
        if kind == 0:
            v[p] = v[p] + value
        else:
            v[p] = value


def _vec3(values, device) -> torch.Tensor:
    return torch.tensor([list(map(float, a)) for a in values], dtype=torch.float32, device=device).reshape(-1, 3)


def _times(items, device) -> torch.Tensor:
    """[start, end] per boundary [M, 2] (float32: 1e30 stays finite)."""
    return torch.tensor([[b.start, b.end] for b in items], dtype=torch.float32, device=device).reshape(-1, 2)


class Boundaries:
    """The config's boundary list as device arrays (allocated once) plus the particle regions."""

    def __init__(self, items, device: str, shape=(1, 1, 1), wall_cells: int = 0):
        ensure_warp()
        planes = [b for b in items if isinstance(b, PlaneBoundary)]
        boxes = [b for b in items if isinstance(b, CuboidBoundary)]
        spheres = [b for b in items if isinstance(b, SphereBoundary)]
        self.regions = [b for b in items if isinstance(b, ParticleRegion)]
        known = (PlaneBoundary, CuboidBoundary, SphereBoundary, ParticleRegion)
        unknown = [b for b in items if not isinstance(b, known)]
        if unknown:
            raise SimulationError(
                f"sim.boundaries: unsupported entry {unknown[0]!r}; use PlaneBoundary, CuboidBoundary, "
                "SphereBoundary or ParticleRegion"
            )
        for b in planes:
            if b.mode not in PLANE_MODE_IDS:
                raise SimulationError(f"sim.boundaries: plane mode '{b.mode}' is not one of {sorted(PLANE_MODE_IDS)}")
        normals = _vec3([b.normal for b in planes], device)
        normals = normals / normals.norm(dim=1, keepdim=True).clamp_min(1e-12)
        push = _vec3([b.push for b in boxes], device)
        push = push / push.norm(dim=1, keepdim=True).clamp_min(1e-12)  # (0, 0, 0) stays: sticky
        self.t = dict(
            plane_point=_vec3([b.point for b in planes], device),
            plane_normal=normals,
            plane_mode=torch.tensor([PLANE_MODE_IDS[b.mode] for b in planes], dtype=torch.int32, device=device),
            plane_mu=torch.tensor([float(b.friction) for b in planes], dtype=torch.float32, device=device),
            box_lower=_vec3([b.lower for b in boxes], device),
            box_upper=_vec3([b.upper for b in boxes], device),
            box_velocity=_vec3([b.velocity for b in boxes], device),
            box_time=_times(boxes, device),
            box_push=push,
            sphere_centre=_vec3([b.center for b in spheres], device),
            sphere_radius=torch.tensor([float(b.radius) for b in spheres], dtype=torch.float32, device=device),
            sphere_velocity=_vec3([b.velocity for b in spheres], device),
            sphere_time=_times(spheres, device),
        )
        vec = {
            "plane_point": wp.vec3,
            "plane_normal": wp.vec3,
            "box_lower": wp.vec3,
            "box_upper": wp.vec3,
            "box_velocity": wp.vec3,
            "box_time": wp.vec2,
            "box_push": wp.vec3,
            "sphere_centre": wp.vec3,
            "sphere_velocity": wp.vec3,
            "sphere_time": wp.vec2,
        }
        self.colliders = Colliders()
        for k, t in self.t.items():
            setattr(self.colliders, k, wp.from_torch(t, dtype=vec[k]) if k in vec else wp.from_torch(t))
        self.colliders.shape = wp.vec3i(*shape)
        self.colliders.wall_cells = int(wall_cells)

    def region_table(self, times: list, dt: float) -> tuple[list, list]:
        """Per substep of a frame (start times `times`), per region: active (0/1) and its value, the
        velocity change spread over the region's duration (impulse) or the velocity (override),
        decided on the host in double precision (no device sync)."""
        on, value = [], []
        for t in times:
            for r in self.regions:
                if r.kind == "impulse":
                    duration = max(r.end - r.start, dt)
                    on.append(int(r.start <= t < r.start + duration))
                    value.append([float(c) * dt / duration for c in r.delta_v])
                elif r.kind == "velocity":
                    on.append(int(r.start <= t <= r.end + 0.5 * dt))
                    value.append([float(c) for c in r.velocity])
                else:
                    raise SimulationError(f"sim.boundaries: region kind '{r.kind}' is not 'impulse' or 'velocity'")
        return on, value

    def apply_regions(self, x_wp, v_wp, n: int, clock, device: str, active=None):
        """Launch every timed particle region (each checks its activity in the clock's table); with
        `active` (this substep's on-flags, known on the host) only the active ones."""
        for i, r in enumerate(self.regions):
            if active is not None and not active[i]:
                continue
            kind = 0 if r.kind == "impulse" else 1
            launch(apply_particle_region, n, [x_wp, v_wp, wp.vec3(*r.lower), wp.vec3(*r.upper), kind, i, clock], device)
