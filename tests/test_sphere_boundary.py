"""`SphereBoundary`, a kinematic rigid sphere on the grid (and the one-sided `CuboidBoundary.push` plate):
inside it a node loses only the part of its velocity that approaches the sphere's surface relative to the
sphere, so it pushes material and never pulls or glues it. The rule on single nodes against hand-computed
values; a free block hit by it gains +x momentum and is not dragged back when it recedes; the per-fragment
box storage applies it exactly as the slot storage; the differentiable kernels' adjoint of the boundary step
is the transpose of its Jacobian; bad spheres get one sentence; a sphere survives a TOML round trip."""

from __future__ import annotations

import math

import pytest
import tomllib
import torch
import warp as wp
from simutil import block, config, particles
from simutil import boundaries_applied as applied

from fracture_gs import sim as S
from fracture_gs.config import CuboidBoundary, PlaneBoundary, SphereBoundary
from fracture_gs.errors import ConfigError, SimulationError
from fracture_gs.io.config import config_from_dict, dump_config, load_config, validate
from fracture_gs.sim.physics.boundary import Boundaries

wp.set_module_options({"enable_backward": False})

pytestmark = pytest.mark.usefixtures("one_thread")


# a ball of radius 0.1 at (0.5, 0.5, 0.5) at t = 0.1 s, moving +x at 2 m/s: at t = 0.15 its centre is at x = 0.6
BALL = SphereBoundary(center=(0.5, 0.5, 0.5), radius=0.1, velocity=(2.0, 0.0, 0.0), start=0.1, end=1.0)


def test_sphere_rule_on_single_nodes():
    """At t = 0.15 s (centre (0.6, 0.5, 0.5)): a node inside moving toward the surface relative to the ball
    loses exactly that normal part (v = (−1, 0.3, 0) at n = +x: v_rel·n = −3, so v → (2, 0.3, 0)); a node
    moving away from it, one outside it, and any node before `start` or after `end` keep their velocity; a
    node at rest at n = (0.6, 0.8, 0) gets the ball's normal velocity (v_s·n) n = (0.72, 0.96, 0)."""
    v = [(-1.0, 0.3, 0.0), (3.0, 0.3, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.5, -0.2, 0.1)]
    x = [(0.65, 0.5, 0.5), (0.65, 0.5, 0.5), (0.75, 0.5, 0.5), (0.63, 0.54, 0.5), (0.52, 0.5, 0.5)]
    out = applied([BALL], v, x, 0.15)
    want = [(2.0, 0.3, 0.0), (3.0, 0.3, 0.0), (-1.0, 0.0, 0.0), (0.72, 0.96, 0.0)]
    torch.testing.assert_close(out[:4], torch.tensor(want, dtype=torch.float64), atol=1e-5, rtol=0)
    # the last node is inside at t = 0.15 behind the centre (n = −x, v_rel·n = 1.5 > 0): left alone
    torch.testing.assert_close(out[4], torch.tensor(v[4], dtype=torch.float64), atol=1e-7, rtol=0)
    # 0.05 m ahead of where the centre would be if the ball were active (at t = 0.05 it starts at x = 0.5;
    # at t = 1.01 it would be at 0.5 + 2·0.91): inactive, so these approaching nodes are left alone
    for t, where in ((0.05, 0.55), (1.01, 2.37)):
        assert applied([BALL], v[:1], [(where, 0.5, 0.5)], t)[0].tolist() == pytest.approx(v[0], abs=1e-7)
    assert applied([BALL], v[:1], [(2.35, 0.5, 0.5)], 0.999)[0].tolist() == pytest.approx([2.0, 0.3, 0.0], abs=1e-4)


def test_push_plate_rule_and_sticky_grips_on_single_nodes():
    """A cuboid with `push` = −z moving down at 0.2 m/s: a node at rest inside gets (0, 0, −0.2) and keeps its
    sideways velocity (no glue); one falling faster than the plate is left alone; a node below it is
    untouched. Without `push` (a grip) the node takes the box's velocity whole."""
    plate = CuboidBoundary(lower=(0.0, 0.0, 0.5), upper=(1.0, 1.0, 0.6), velocity=(0.0, 0.0, -0.2), push=(0, 0, -1))
    grip = CuboidBoundary(lower=(0.0, 0.0, 0.5), upper=(1.0, 1.0, 0.6), velocity=(0.0, 0.0, -0.2))
    v = [(0.3, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)]
    x = [(0.5, 0.5, 0.52), (0.5, 0.5, 0.52), (0.5, 0.5, 0.45)]
    out = applied([plate], v, x, 0.1)  # the plate now spans z ∈ [0.48, 0.58]
    want = [(0.3, 0.0, -0.2), (0.0, 0.0, -1.0), (0.0, 0.0, 1.0)]
    torch.testing.assert_close(out, torch.tensor(want, dtype=torch.float64), atol=1e-6, rtol=0)
    assert applied([grip], v[:1], x[:1], 0.1)[0].tolist() == pytest.approx([0.0, 0.0, -0.2], abs=1e-7)


def _ball_and_block(ball, frames, dt=0.01):
    """A free 0.15 m cube (E = 20 kPa, ρ = 500) at rest in the middle of a 32³ grid, no gravity, and `ball`:
    the simulator after `frames` frames, the momentum [kg m/s] after each and how deep the deepest particle
    then lies inside the ball [m]."""
    x, vol = block((0.45, 0.42, 0.42), (0.6, 0.58, 0.58), 1 / 64)
    sim = S.Simulator(config(32, dt=1e-3, adaptive_dt=True, boundaries=[ball]), particles(x, vol, 500.0, E=2e4), "cpu")
    m = sim.particles.mass.double()
    momenta, depth = [], []
    for f in range(frames):
        sim.advance(dt)
        momenta.append((m[:, None] * sim.particles.v.double()).sum(0))
        centre = torch.tensor(ball.center) + (f + 1) * dt * torch.tensor(ball.velocity)
        depth.append(ball.radius - float((sim.particles.x - centre).norm(dim=1).min()))
    return sim, torch.stack(momenta), depth  # [frames, 3], [frames]


def test_a_ball_pushes_a_free_block_along_its_path():
    """A ball (r = 0.1 m, 1 m/s along +x) hits a free block: momentum appears along +x only (the hit is
    centred: |p_y|, |p_z| < 2 % of p_x) and never decreases while the ball pushes; the block ends between the
    ball's speed (it is ahead of it) and twice it (an elastic body leaving a rigid wall moving at v_s leaves at
    most at 2 v_s); no particle ever lies more than one cell (1/32 m) inside the ball."""
    ball = S.SphereBoundary(center=(0.33, 0.5, 0.5), radius=0.1, velocity=(1.0, 0.0, 0.0))
    sim, p, depth = _ball_and_block(ball, 18)
    mass = float(sim.particles.mass.double().sum())
    assert float(p[-1, 0]) > 0 and float(p[:, 1:].abs().max()) < 0.02 * float(p[-1, 0])
    assert bool((p[1:, 0] >= p[:-1, 0] - 1e-6 * mass).all()), "the push never takes momentum back"
    v_cm = float(p[-1, 0]) / mass
    assert 0.95 <= v_cm <= 2.0, f"block speed {v_cm:.3f} m/s against the ball's 1 m/s"
    assert max(depth) > 0.1 / 32, "the ball reached the block"
    assert max(depth) < 1 / 32, f"material {max(depth) * 32:.2f} cells inside the ball: it went through"


def test_a_receding_ball_does_not_pull():
    """A ball overlapping a block's −x face moves away along −x at 1 m/s: the sphere only pushes, so the
    block at rest stays at rest (|p| below 1e-4 of m·1 m/s; a glued ball would drag it at −1 m/s)."""
    ball = S.SphereBoundary(center=(0.4, 0.5, 0.5), radius=0.08, velocity=(-1.0, 0.0, 0.0))
    sim, p, _ = _ball_and_block(ball, 6)
    mass = float(sim.particles.mass.double().sum())
    assert float(p.abs().max()) < 1e-4 * mass, p[-1]
    assert float(sim.particles.v[:, 0].min()) > -1e-3


def _cut_block(storage):
    """A block cut in two along y (the ball's path runs along the cut, so its nodes carry both pieces'
    fields), FractureFields latched, a ball at 1.5 m/s along +x, `sim.grid_storage` = storage."""
    x, vol = block((0.4, 0.4, 0.4), (0.6, 0.6, 0.56), 1 / 64)
    ball = S.SphereBoundary(center=(0.3, 0.5, 0.48), radius=0.08, velocity=(1.5, 0.0, 0.0))
    cfg = config(32, variant="full", dt=1e-3, boundaries=[ball], grid_storage=storage, field_slots=4)
    sim = S.Simulator(cfg, particles(x, vol, 500.0, E=2e4), "cpu")
    sim.latch(S.Topology.from_plane(x, (0.5, 0.5, 0.5), (0.0, 1.0, 0.0), band_width=1.5 / 32))
    for _ in range(12):
        sim.advance(0.005)
    return sim


def test_the_ball_acts_the_same_in_fragment_boxes_and_slots():
    """After a latch the fields live in per-fragment boxes or in slots: the ball is applied in both grid
    updates, so two pieces it drives along +x advance bitwise alike on the CPU (DESIGN.md "Grid storage"),
    and both pieces gain +x momentum."""
    slots, boxes = _cut_block("slots"), _cut_block("boxes")
    assert boxes.boxed and not slots.boxed
    for name in ("x", "v", "F"):
        assert torch.equal(getattr(slots.particles, name), getattr(boxes.particles, name)), name
    P = boxes.particles
    for k in (0, 1):
        piece = P.fragment == k
        assert float((P.mass[piece] * P.v[piece, 0]).sum()) > 0.05 * float(P.mass[piece].sum()), f"piece {k}"


def test_differentiable_boundary_step_adjoint_is_its_jacobian():
    """The differentiable kernels' boundary step (cuboid pusher, sticky cuboid, ball, slip plane) against its
    analytic Jacobian J: the Warp adjoint of v_out is Jᵀ w for a random cotangent w (I − n nᵀ where the ball
    or the plane projects, 0 in the sticky box, I − p pᵀ where the pusher pushes, I elsewhere). A loop over
    the arrays' lengths gave I everywhere; the unrolled loops give Jᵀ w."""
    from fracture_gs.sim.diff import kernels as K

    ball = SphereBoundary(center=(0.4, 0.5, 0.5), radius=0.22, velocity=(1.0, 0.0, 0.0), start=0.0)
    items = [
        CuboidBoundary(lower=(0, 0, 0.85), upper=(1, 1, 1.02), velocity=(0, 0, -0.5), push=(0, 0, -1)),
        CuboidBoundary(lower=(0, 0, 0), upper=(0.25, 1, 1), velocity=(0.1, 0, 0)),
        ball,
        PlaneBoundary(point=(0, 0, 0.15), normal=(0, 0, 1), mode="slip"),
    ]
    n_side = 10
    shape, dx, origin = (n_side,) * 3, 0.1, (0.05, 0.05, 0.05)
    B = Boundaries(items, "cpu", shape, 0)
    n = n_side**3
    g = torch.Generator().manual_seed(3)
    v0, w = torch.randn(n, 3, generator=g), torch.randn(n, 3, generator=g)
    vin = wp.from_torch(v0.clone(), dtype=wp.vec3, requires_grad=True)
    vout = wp.zeros(n, dtype=wp.vec3, device="cpu", requires_grad=True)
    gm = wp.from_torch(torch.ones(n))
    tape = wp.Tape()
    with tape:
        wp.launch(
            K.boundaries,
            dim=n,
            inputs=[gm, vin, 0.0, wp.vec3(*origin), dx, wp.vec3i(*shape), wp.vec3i(0, 0, 0), 0.1, B.colliders],
            outputs=[vout],
            device="cpu",
        )
    vout.grad = wp.from_torch(w.clone(), dtype=wp.vec3)
    tape.backward()
    got = wp.to_torch(vin.grad).double()

    idx = torch.arange(n)
    node = torch.stack([idx // n_side**2, (idx // n_side) % n_side, idx % n_side], 1).double()
    xi = torch.tensor(origin, dtype=torch.float64) + node * dx
    out, J = v0.double().clone(), torch.eye(3, dtype=torch.float64).repeat(n, 1, 1)  # the same order as the kernel

    def project(mask, normal, v_rel):
        nonlocal out
        vn = (v_rel * normal).sum(1)
        hit = mask & (vn < 0)
        out[hit] = out[hit] - vn[hit, None] * normal[hit]
        P = torch.eye(3, dtype=torch.float64) - normal[:, :, None] * normal[:, None, :]
        J[hit] = P[hit] @ J[hit]
        return int(hit.sum())

    t = 0.1
    down = torch.tensor([0.0, 0.0, -1.0], dtype=torch.float64).expand(n, 3)
    plate_v = torch.tensor([0.0, 0.0, -0.5], dtype=torch.float64)
    in_plate = (xi[:, 2] >= 0.85 - 0.05) & (xi[:, 2] <= 1.02 - 0.05)
    pushed = project(in_plate, down, out - plate_v)
    grip = xi[:, 0] <= 0.25 + 0.01 + 1e-9
    out[grip], J[grip] = torch.tensor([0.1, 0.0, 0.0], dtype=torch.float64), 0.0
    c = torch.tensor([0.4 + t, 0.5, 0.5], dtype=torch.float64)
    d = xi - c
    r = d.norm(dim=1, keepdim=True)
    hit_ball = project(r[:, 0] < 0.22, d / r.clamp_min(1e-12), out - torch.tensor([1.0, 0.0, 0.0]).double())
    up = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64).expand(n, 3)
    hit_plane = project(xi[:, 2] < 0.15, up, out)
    assert min(pushed, hit_ball, hit_plane) > 5 and int(grip.sum()) > 5, (pushed, hit_ball, hit_plane)
    torch.testing.assert_close(wp.to_torch(vout).double(), out, atol=1e-5, rtol=0)
    torch.testing.assert_close(got, (J.transpose(1, 2) @ w.double()[:, :, None])[:, :, 0], atol=1e-5, rtol=0)


def test_differentiable_solver_refuses_more_spheres_than_it_unrolls():
    """The differentiable kernels unroll MAX_BOUNDARIES spheres: one more is refused with one sentence."""
    from fracture_gs.sim.diff import DiffSimulator
    from fracture_gs.sim.diff.kernels import MAX_BOUNDARIES

    x, _ = block((0.4, 0.4, 0.4), (0.5, 0.5, 0.5), 1 / 32)
    balls = [S.SphereBoundary(center=(0.1, 0.1, 0.1), radius=0.05) for _ in range(MAX_BOUNDARIES + 1)]
    with pytest.raises(SimulationError, match=r'at most \d+ of type = "sphere"') as info:
        DiffSimulator(config(16, boundaries=balls), x)
    assert "\n" not in str(info.value)


BAD_SPHERES = [
    ("radius = 0.0\n", "sim.boundaries[0].radius", "positive"),
    ("radius = -0.1\n", "sim.boundaries[0].radius", "positive"),
    ("radius = 0.1\ncenter = [nan, 0.5, 0.5]\n", "sim.boundaries[0].center", "finite"),
    ("radius = 0.1\nvelocity = [inf, 0, 0]\n", "sim.boundaries[0].velocity", "finite"),
    ("radius = 0.1\nstart = 0.5\nend = 0.2\n", "sim.boundaries[0].start", "start <= end"),
    ("radius = 0.1\ncentre = [0, 0, 0]\n", "sim.boundaries[0].centre", "did you mean 'center'"),
]


@pytest.mark.parametrize("body,field,fix", BAD_SPHERES, ids=[f"{b[1]}:{b[2]}" for b in BAD_SPHERES])
def test_bad_sphere_gets_one_sentence(tmp_path, body, field, fix):
    """A sphere with a non-positive radius, a non-finite vector, end before start or a misspelt key is
    refused on load with one sentence naming the file, the field and the fix."""
    path = tmp_path / "x.toml"
    path.write_text('[[sim.boundaries]]\ntype = "sphere"\n' + body)
    with pytest.raises(ConfigError) as info:
        load_config(path)
    err = info.value
    assert err.field == field and fix in str(err) and "\n" not in str(err), str(err)


def test_sphere_and_push_plate_round_trip_through_toml():
    """dump_config then loading the text gives the same boundaries (sphere and pushing cuboid, field by
    field), and the loaded config validates."""
    cfg = load_config("bread")
    ball = SphereBoundary(center=(0.1, 0.5, 0.25), radius=0.06, velocity=(3.0, 0.0, 0.0), start=0.0, end=0.25)
    plate = CuboidBoundary(lower=(0, 0, 0.6), upper=(1, 1, 0.7), velocity=(0, 0, -0.2), end=0.5, push=(0, 0, -1))
    cfg.sim.boundaries = [ball, plate]
    text = dump_config(cfg)
    assert 'type = "sphere"' in text
    back = validate(config_from_dict(tomllib.loads(text)))
    assert back.sim.boundaries == [ball, plate]
    assert math.isclose(back.sim.boundaries[0].radius, 0.06)


def test_a_ball_in_a_built_in_scenes_config_pushes_it(tmp_path):
    """`plane_drop` (a bar falling under gravity, nothing else pushing it sideways: its mean x velocity stays 0
    until it lands at ≈ 0.2 s) with a `type = "sphere"` table added in its TOML, run through the pipeline
    for FractureFields: the ball flying +x at 3 m/s into the bar's −x end gives the bar a mean +x velocity
    within 4 frames, at most twice the ball's (the elastic limit)."""
    from fracture_gs.pipeline import load_scene, make_simulator, simulate

    base = load_config("plane_drop")
    base.particles = 1500
    lowest_x = float(load_scene(base).means[:, 0].min())
    path = tmp_path / "ball.toml"
    path.write_text(
        'extends = "plane_drop"\nparticles = 1500\nframes = 4\n\n[[sim.boundaries]]\ntype = "plane"\n'
        'point = [0.0, 0.0, 0.1]\nnormal = [0.0, 0.0, 1.0]\n\n[[sim.boundaries]]\ntype = "sphere"\n'
        f"center = [{lowest_x - 0.07}, 0.5, 0.44]\nradius = 0.06\nvelocity = [3.0, 0.0, 0.0]\n"
    )
    cfg = load_config(path)
    assert isinstance(cfg.sim.boundaries[1], SphereBoundary)
    gs = load_scene(cfg)
    sim = make_simulator(cfg, gs, "full", "cpu")
    for _ in simulate(sim, gs.covariances().float(), cfg.frames, cfg.frame_dt, diagnostics=False):
        pass
    m, v = sim.particles.mass.double(), sim.particles.v.double()
    v_cm = float((m * v[:, 0]).sum() / m.sum())
    assert 0.5 < v_cm <= 6.0, v_cm
