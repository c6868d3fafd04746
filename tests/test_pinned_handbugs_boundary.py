"""Hand-written bug campaign, boundaries (`sim.physics.boundary`): rules the earlier tests left open.

- A pusher's `push` is a direction, whatever its length: a node at rest inside a plate that moves down at
  0.5 m/s with push = (0, 0, −3) takes exactly the plate's normal speed, v = (0, 0, −0.5) (v − min(0, (v − v_b)·p̂) p̂
  with p̂ the unit push), not (0, 0, −4.5) as an unnormalized (0, 0, −3) would give; a node already moving down
  faster than the plate keeps its velocity (the pusher never pulls).
"""

import pytest
import torch
import warp as wp

from fracture_gs.config import CuboidBoundary
from fracture_gs.runtime import ensure_warp
from fracture_gs.sim.physics.boundary import Boundaries, Colliders, apply_boundaries

ensure_warp()


@wp.kernel
def _apply(v: wp.array(dtype=wp.vec3), xi: wp.vec3, t: float, c: Colliders, out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = apply_boundaries(v[i], wp.vec3i(8, 8, 8), xi, t, c)


def _after(items, velocities, xi=(0.5, 0.5, 0.5), t=0.0):
    b = Boundaries(items, "cpu", (16, 16, 16), 0)
    v = wp.from_torch(torch.tensor(velocities, dtype=torch.float32), dtype=wp.vec3)
    out = wp.zeros(len(velocities), dtype=wp.vec3, device="cpu")
    wp.launch(_apply, dim=len(velocities), inputs=[v, wp.vec3(*xi), float(t), b.colliders, out], device="cpu")
    return out.numpy().tolist()


@pytest.mark.parametrize("length", [1.0, 3.0, 0.25])
def test_a_pusher_takes_its_direction_not_its_length(length):
    """Plate around the node, moving at (0, 0, −0.5) m/s, push = (0, 0, −length): a node at rest gets (0, 0, −0.5);
    a node moving at (0.25, 0, −1) (away from the plate, faster than it) is left as it is."""
    plate = CuboidBoundary(lower=(0.25, 0.25, 0.25), upper=(0.75, 0.75, 0.75), velocity=(0.0, 0.0, -0.5),
                           push=(0.0, 0.0, -length))  # fmt: skip
    rest, fast = _after([plate], [(0.0, 0.0, 0.0), (0.25, 0.0, -1.0)])
    assert rest == pytest.approx([0.0, 0.0, -0.5], abs=1e-7)
    assert fast == pytest.approx([0.25, 0.0, -1.0], abs=1e-7)
