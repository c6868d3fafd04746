"""Pinhole cameras in the OpenCV convention (x right, y down, z forward), as gsplat expects.

`viewmat` maps world to camera: p_c = R p_w + t, with the rows of R the camera axes in world
coordinates; the camera centre is c = −Rᵀ t. Intrinsics K = [[f, 0, W/2], [0, f, H/2], [0, 0, 1]]
with f = (H/2) / tan(fov_y/2) (square pixels). A pixel (u, v) covers [u, u+1) × [v, v+1).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import torch
from torch import Tensor

from ..config import CameraConfig
from ..errors import RenderError
from ..io.video import MAX_FRAME_SIDE


@dataclass
class Camera:
    viewmat: Tensor  # [4, 4] world → camera
    K: Tensor  # [3, 3] intrinsics
    width: int
    height: int

    @property
    def campos(self) -> Tensor:  # [3]
        """Camera centre in world coordinates, −Rᵀ t."""
        R, t = self.viewmat[:3, :3], self.viewmat[:3, 3]
        return -R.T @ t

    @property
    def fov_deg(self) -> float:
        """Vertical field of view [degrees]."""
        return math.degrees(2 * math.atan(0.5 * self.height / float(self.K[1, 1])))

    def to(self, device=None, dtype=None) -> Camera:
        return Camera(
            self.viewmat.to(device=device, dtype=dtype), self.K.to(device=device, dtype=dtype), self.width, self.height
        )

    def project(self, points: Tensor) -> tuple[Tensor, Tensor]:  # [N,3] -> [N,2] pixels, [N] depth
        """Pinhole projection u = f_x x/z + c_x, v = f_y y/z + c_y of world points; depth = z."""
        vm, K = self.viewmat.to(points), self.K.to(points)
        pc = points @ vm[:3, :3].T + vm[:3, 3]
        z = pc[:, 2]
        uv = pc[:, :2] / z[:, None] * torch.stack([K[0, 0], K[1, 1]]) + torch.stack([K[0, 2], K[1, 2]])
        return uv, z


def _vec(v, dtype=torch.float64) -> Tensor:
    return torch.as_tensor(v, dtype=dtype).reshape(3)


MAX_SIDE = MAX_FRAME_SIDE  # pixels: the largest image side a camera may have (the widest frame the encoder takes)


def _point(where: str, name: str, v) -> Tensor:
    """A camera argument that is a point or direction: 3 finite numbers, else RenderError naming it."""
    try:
        t = _vec(v)
    except (TypeError, ValueError, RuntimeError):
        raise RenderError(
            f"{where}: {name} must be 3 numbers (x, y, z), not {v!r:.60}; pass e.g. (0.0, 0.0, 1.0)."
        ) from None
    if not bool(torch.isfinite(t).all()):
        raise RenderError(f"{where}: {name} = {t.tolist()} is not finite; pass 3 finite numbers (metres).")
    return t


def _check_image(where: str, fov_deg, width, height) -> None:
    """A field of view strictly between 0° and 180° and whole image sides of 1 to MAX_SIDE pixels."""
    for name, v in (("width", width), ("height", height)):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) and not (isinstance(v, float) and v.is_integer()):
            raise RenderError(f"{where}: {name} = {v!r:.40} is not a whole number of pixels; pass e.g. {name}=256.")
        if not 1 <= v <= MAX_SIDE:
            raise RenderError(f"{where}: {name} = {v} is outside 1 to {MAX_SIDE} pixels; pass e.g. {name}=256.")
    if isinstance(fov_deg, bool) or not isinstance(fov_deg, numbers.Real) or not 0 < fov_deg < 180:
        raise RenderError(
            f"{where}: fov_deg = {fov_deg!r:.40} is not a field of view between 0 and 180 degrees; pass e.g. "
            "fov_deg=40."
        )


def intrinsics(fov_deg: float, width: int, height: int) -> Tensor:  # [3,3]
    """K from the vertical field of view, principal point at the image centre."""
    f = 0.5 * height / math.tan(math.radians(fov_deg) / 2)
    return torch.tensor([[f, 0.0, width / 2], [0.0, f, height / 2], [0.0, 0.0, 1.0]])


def look_at(eye, target, up=(0.0, 0.0, 1.0), fov_deg: float = 40.0, width: int = 256, height: int = 256) -> Camera:
    """Camera at `eye` looking at `target`; image up is as close to `up` as possible.

    z = (target − eye)/|·|, x = z × up /|·| (right), y = z × x (down); R = [x; y; z], t = −R eye.
    """
    eye, target, up = (_point("look_at", k, v) for k, v in (("eye", eye), ("target", target), ("up", up)))
    _check_image("look_at", fov_deg, width, height)
    if not float(up.norm()) > 0:
        raise RenderError("look_at: up is the zero vector; pass the world's up direction, e.g. up=(0, 0, 1).")
    z = target - eye
    if z.norm() < 1e-12:
        raise RenderError("look_at: eye and target coincide; put the camera away from the point it looks at.")
    z = z / z.norm()
    x = torch.linalg.cross(z, up)
    if x.norm() < 1e-9 * max(up.norm().item(), 1e-30):  # up ∥ view direction: pick another up
        alt = torch.tensor([1.0, 0.0, 0.0], dtype=z.dtype)
        if abs(float(z @ alt)) > 0.9:
            alt = torch.tensor([0.0, 1.0, 0.0], dtype=z.dtype)
        x = torch.linalg.cross(z, alt)
    x = x / x.norm()
    y = torch.linalg.cross(z, x)
    R = torch.stack([x, y, z])
    vm = torch.eye(4, dtype=torch.float64)
    vm[:3, :3], vm[:3, 3] = R, -R @ eye
    return Camera(vm.float(), intrinsics(fov_deg, width, height).float(), int(width), int(height))


def _perp_basis(up: Tensor) -> tuple[Tensor, Tensor]:
    """Orthonormal e1, e2 spanning the plane ⟂ up (e1 from the world axis least aligned with up)."""
    a = torch.eye(3, dtype=up.dtype)[int(torch.argmin(up.abs()))]
    e1 = a - (a @ up) * up
    e1 = e1 / e1.norm()
    return e1, torch.linalg.cross(up, e1)


def orbit(
    target,
    radius: float,
    elevation_deg: float,
    azimuth_deg: float,
    up=(0.0, 0.0, 1.0),
    fov_deg: float = 40.0,
    width: int = 256,
    height: int = 256,
) -> Camera:
    """Camera on a sphere about `target`: eye = target + r (cos e (cos a e1 + sin a e2) + sin e up)."""
    target, up = _point("orbit", "target", target), _point("orbit", "up", up)
    for name, v in (("radius", radius), ("elevation_deg", elevation_deg), ("azimuth_deg", azimuth_deg)):
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
            raise RenderError(f"orbit: {name} = {v!r:.40} is not a finite number; pass e.g. {name}=1.0.")
    if not radius > 0:
        raise RenderError(f"orbit: radius = {radius!r} must be a positive distance from target; pass e.g. radius=1.5.")
    if not float(up.norm()) > 0:
        raise RenderError("orbit: up is the zero vector; pass the world's up direction, e.g. up=(0, 0, 1).")
    up = up / up.norm()
    e1, e2 = _perp_basis(up)
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    eye = target + radius * (math.cos(el) * (math.cos(az) * e1 + math.sin(az) * e2) + math.sin(el) * up)
    return look_at(eye, target, up, fov_deg, width, height)


def rotate_about_axis(p: Tensor, axis: Tensor, center: Tensor, angle_deg: float) -> Tensor:  # [3]
    """Rodrigues rotation of point p by angle about the line through `center` along `axis`."""
    k = axis / axis.norm()
    v = p - center
    th = math.radians(angle_deg)
    v = v * math.cos(th) + torch.linalg.cross(k, v) * math.sin(th) + k * (k @ v) * (1 - math.cos(th))
    return center + v


def frame_camera(scene_cfg, frame: int) -> Camera:
    """The camera of a run's frame (`SceneConfig`): the configured camera at progress frame / frames."""
    r = scene_cfg.render
    return from_config(r.camera, int(r.width), int(r.height), t=frame / max(scene_cfg.frames, 1))


def from_config(cfg: CameraConfig, width: int, height: int, t: float = 0.0) -> Camera:
    """The configured camera at run progress t ∈ [0, 1]: the eye turned by orbit_degrees·t about
    the axis `up` through `target`."""
    eye, target, up = _vec(cfg.eye), _vec(cfg.target), _vec(cfg.up)
    if cfg.orbit_degrees:
        eye = rotate_about_axis(eye, up, target, cfg.orbit_degrees * float(t))
    return look_at(eye, target, up, cfg.fov_deg, width, height)
