"""A camera for a captured scene: one that frames the fitted object, or one of the trainer's views.

`auto` looks at the object from the −y side (its long axis, x, runs across the image), 20° above
the horizon, far enough that the object, the room a load needs (the opening of a pull, the floor
of a drop) and a margin fit the field of view. `trainer` takes view `capture.view` of the
trainer's cameras.json into the simulation frame: the picture the user already knows.
"""

from __future__ import annotations

import math

import torch

from ..config import CameraConfig
from .fit import TrainerCamera
from .transform import SceneTransform


def frame_box(lo, hi, width: int, height: int, fov_deg: float = 40.0, elevation_deg: float = 20.0) -> CameraConfig:
    """A look-at camera from −y and above that shows the box [lo, hi] (metres) with a 15 % margin."""
    lo, hi = torch.as_tensor(lo, dtype=torch.float64), torch.as_tensor(hi, dtype=torch.float64)
    centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    tan_v = math.tan(math.radians(fov_deg) / 2)
    tan_h = tan_v * width / height
    e = math.radians(elevation_deg)
    # half-extents seen from the camera: x across; z and y (foreshortened by the elevation) up
    across = float(half[0]) * 1.15
    upward = (float(half[2]) * math.cos(e) + float(half[1]) * math.sin(e)) * 1.15
    depth = float(half[1]) * math.cos(e) + float(half[2]) * math.sin(e)
    dist = max(across / tan_h, upward / tan_v) + depth
    eye = centre + dist * torch.tensor([0.0, -math.cos(e), math.sin(e)], dtype=torch.float64)
    return CameraConfig(
        eye=tuple(float(v) for v in eye),
        target=tuple(float(v) for v in centre),
        up=(0.0, 0.0, 1.0),
        fov_deg=fov_deg,
    )


def trainer_view(cam: TrainerCamera, fit: SceneTransform, target) -> CameraConfig:
    """The trainer's view `cam` in the simulation frame, looking along its own axis (the look-at point
    is the fitted object's centre projected onto that axis)."""
    Q = fit.rotation
    eye = fit.points(cam.position[None])[0]
    forward = Q @ cam.rotation[:, 2]
    up = -(Q @ cam.rotation[:, 1])
    depth = max(float((torch.as_tensor(target, dtype=torch.float64) - eye) @ forward), 1e-3)
    fov = math.degrees(2 * math.atan(cam.height / (2 * cam.fy)))
    return CameraConfig(
        eye=tuple(float(v) for v in eye),
        target=tuple(float(v) for v in eye + depth * forward),
        up=tuple(float(v) for v in up),
        fov_deg=fov,
    )
