"""Where the object is and which way is up: the trainer's cameras, the region of interest, and the
similarity transform that puts the object into the simulation domain.

The fit: rotate the scene's up axis onto +z, then turn about z so the object's longest horizontal
principal axis lies along x (a pull load grips its two ends), scale so its longest side is
`capture.size` metres, and centre it at (0.5, 0.5, 0.5). The result is stored as (scale, rotation,
offset) in the config, so a run can be repeated and outputs taken back to the scene's own frame.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import torch

from ..config import CaptureConfig
from ..errors import ArgumentError, SceneError
from ..io.config.combinations import UP_AXES
from ..io.config.validate import ROTATION_TOLERANCE, is_finite_number
from .transform import SceneTransform

AXES = UP_AXES  # capture.up → the scene axis it names
CENTRE = (0.5, 0.5, 0.5)
"""Where the fitted object's bounding-box centre goes [m]."""


@dataclass
class TrainerCamera:
    """One view of the reference trainer's cameras.json: centre and camera-to-world rotation (OpenCV
    axes: x right, y down, z forward), focal lengths and image size."""

    position: torch.Tensor  # [3] float64
    rotation: torch.Tensor  # [3, 3] float64, columns = camera axes in the world
    fx: float
    fy: float
    width: int
    height: int
    name: str = ""


def find_cameras_json(ply: Path, explicit: Optional[str]) -> Optional[Path]:
    """The trainer's cameras.json: the configured path, else beside the PLY or up to three folders up
    (the reference trainer writes model/cameras.json and model/point_cloud/iteration_N/point_cloud.ply)."""
    if explicit:
        p = Path(explicit).expanduser()
        if not p.is_file():
            raise SceneError(f"{p}: capture.cameras_json does not exist; fix the path or remove the key.")
        return p
    folder = ply.resolve().parent
    for _ in range(4):
        if (folder / "cameras.json").is_file():
            return folder / "cameras.json"
        folder = folder.parent
    return None


MAX_IMAGE_SIDE = 100_000
"""Pixels: the largest image side a cameras.json view may claim."""
MAX_CAMERA_DISTANCE = 1e9
"""Scene units: the farthest a view's centre may be from the origin on any axis (a trainer's scenes span
hundreds; beyond this the fitted camera is no longer a float32 position)."""
MAX_ASPECT = 10.0
"""The widest (or tallest) image a view may claim, width over height: the rendered panel keeps it."""
FOV_RANGE = (0.1, 179.0)
"""Degrees: the field of view a view's focal length may give across its image (the renderer takes up to 179)."""
_CAMERA_FIX = (
    "fix that entry, point capture.cameras_json at the trainer's file, or set capture.up and "
    'capture.camera = "auto" so the file is not needed'
)


def read_cameras(path: Path) -> list[TrainerCamera]:
    """The views of a cameras.json written by the reference 3DGS trainer; a view with a missing key, a value
    of the wrong type, NaN or inf, a non-positive focal length or image size, or a rotation that is not a
    proper rotation raises SceneError naming the file, the view and the key."""
    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise ArgumentError(
            f"read_cameras: path must be the path of a cameras.json (str or pathlib.Path), not {path!r:.40}; pass "
            "e.g. Path('model/cameras.json')."
        )
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8-sig"))  # a BOM (Windows editors) is not an error
    except RecursionError:
        raise SceneError(
            f"{path}: not a trainer cameras.json (its arrays nest too deeply); point capture.cameras_json at the "
            f'trainer\'s file or set capture.up and capture.camera = "auto".'
        ) from None
    except (OSError, ValueError) as exc:
        raise SceneError(
            f"{path}: not a trainer cameras.json ({' '.join(str(exc).split())}); point capture.cameras_json at the "
            f'trainer\'s file or set capture.up and capture.camera = "auto".'
        ) from None
    if not isinstance(data, list) or not data:
        raise SceneError(
            f"{path}: cameras.json must be a non-empty list of views, not {_describe(data)}; point "
            f'capture.cameras_json at the trainer\'s file or set capture.up and capture.camera = "auto".'
        )
    return [_camera(path, i, c) for i, c in enumerate(data)]


def _short_name(name: str) -> str:
    """A view's image name as a message shows it: one line, at most 40 characters."""
    text = " ".join(name.split())
    return text if len(text) <= 40 else text[:39] + "…"


def _describe(v) -> str:
    if isinstance(v, bool):
        return f"the boolean {str(v).lower()}"
    if isinstance(v, (int, float)):
        return f"the number {v!r:.40}" if is_finite_number(v) else f"the non-finite number {v!r:.40}"
    if isinstance(v, str):
        return f"the string {v[:40]!r}"
    if isinstance(v, list):
        return f"a list of {len(v)}"
    if isinstance(v, dict):
        return "an object"
    return "null" if v is None else type(v).__name__


def _camera(path: Path, i: int, c) -> TrainerCamera:
    """One view of cameras.json, checked key by key."""
    name = c.get("img_name") if isinstance(c, dict) else None
    where = f"{path}: camera {i}" + (f" ({_short_name(name)})" if isinstance(name, str) and name.strip() else "")

    def bad(key: str, problem: str) -> SceneError:
        return SceneError(f"{where}: {key} {problem}; {_CAMERA_FIX}.")

    if not isinstance(c, dict):
        raise SceneError(
            f"{where} is {_describe(c)}, not an object with position, rotation, fx, fy, width and height; "
            f"{_CAMERA_FIX}."
        )
    for key in ("position", "rotation", "fx", "fy", "width", "height"):
        if key not in c:
            raise bad(key, "is missing")
    pos = c["position"]
    if not isinstance(pos, list) or len(pos) != 3:
        raise bad("position", f"must be 3 finite numbers, not {_describe(pos)}")
    if not all(is_finite_number(v) for v in pos):
        raise bad(
            "position",
            f"holds {_describe(next(v for v in pos if not is_finite_number(v)))}; it must be 3 finite numbers",
        )
    if max(abs(float(v)) for v in pos) > MAX_CAMERA_DISTANCE:
        raise bad("position", f"= {pos} is more than {MAX_CAMERA_DISTANCE:g} scene units from the origin")
    rot = c["rotation"]
    rows_ok = isinstance(rot, list) and len(rot) == 3 and all(isinstance(r, list) and len(r) == 3 for r in rot)
    if not rows_ok:
        raise bad("rotation", f"must be a 3×3 array of finite numbers, not {_describe(rot)}")
    wrong = next((v for r in rot for v in r if not is_finite_number(v)), None)
    if wrong is not None:
        raise bad("rotation", f"holds {_describe(wrong)}; it must be a 3×3 array of finite numbers")
    R = torch.tensor(rot, dtype=torch.float64)
    err = float((R.T @ R - torch.eye(3, dtype=torch.float64)).abs().max())
    if err > ROTATION_TOLERANCE:
        raise bad("rotation", f"is not a rotation (RᵀR differs from the identity by {err:.3g})")
    if float(torch.linalg.det(R)) < 0:
        raise bad("rotation", "is a reflection (determinant −1), not a camera rotation")
    for key in ("fx", "fy"):
        if not is_finite_number(c[key]) or not c[key] > 0:
            raise bad(key, f"must be a positive focal length in pixels, not {_describe(c[key])}")
    for key in ("width", "height"):
        v = c[key]
        if not (is_finite_number(v) and float(v).is_integer() and 1 <= v <= MAX_IMAGE_SIDE):
            raise bad(key, f"must be a whole number of pixels from 1 to {MAX_IMAGE_SIDE:,}, not {_describe(v)}")
    return TrainerCamera(
        position=torch.tensor(pos, dtype=torch.float64),
        rotation=R,
        fx=float(c["fx"]),
        fy=float(c["fy"]),
        width=int(c["width"]),
        height=int(c["height"]),
        name=str(name) if isinstance(name, (str, int)) and not isinstance(name, bool) else "",
    )


def check_view(path, index: int, cam: TrainerCamera) -> None:
    """The view `capture.camera = "trainer"` draws from: an image shape the panel can keep (at most MAX_ASPECT:1)
    and focal lengths whose field of view the renderer can draw (FOV_RANGE), else SceneError naming the file, the
    view and the key (the file itself may hold such views: only the chosen one is drawn)."""
    where = f"{path}: camera {index}" + (f" ({_short_name(cam.name)})" if cam.name.strip() else "")
    fix = 'pick another capture.view, or set capture.camera = "auto" to frame the object instead'
    if not 1 / MAX_ASPECT <= cam.width / cam.height <= MAX_ASPECT:
        raise SceneError(
            f"{where}: width and height ({cam.width}×{cam.height}) are not a camera image (over {MAX_ASPECT:g}:1); "
            f"{fix}."
        )
    for key, side in (("fx", "width"), ("fy", "height")):
        f, pixels = getattr(cam, key), getattr(cam, side)
        fov = math.degrees(2 * math.atan(pixels / (2 * f)))
        if not FOV_RANGE[0] <= fov <= FOV_RANGE[1]:
            raise SceneError(
                f"{where}: {key} = {f:g} px gives a field of view of {fov:.3g}° across its {pixels}-pixel {side}, "
                f"outside {FOV_RANGE[0]:g}° to {FOV_RANGE[1]:g}°; {fix}."
            )


def detect_up(cap: CaptureConfig, cameras: list[TrainerCamera]) -> tuple[torch.Tensor, str]:
    """(unit up vector in scene coordinates, how it was chosen)."""
    if cap.up != "auto":
        return torch.tensor(AXES[cap.up], dtype=torch.float64), f"up axis {cap.up} (capture.up)"
    if cameras:
        down = torch.stack([c.rotation[:, 1] for c in cameras]).mean(0)  # cameras' y axes point down
        if float(down.norm()) > 1e-6:
            up = -down / down.norm()
            near = max(AXES, key=lambda k: float(up @ torch.tensor(AXES[k], dtype=torch.float64)))
            return up, f"up axis from the {len(cameras)} trainer cameras (closest to {near})"
    return torch.tensor(AXES["-y"], dtype=torch.float64), "up axis -y assumed (COLMAP's convention; set capture.up)"


def rotation_onto_z(u: torch.Tensor) -> torch.Tensor:
    """The smallest rotation taking unit vector u to +z (Rodrigues), [3, 3] float64."""
    z = torch.tensor([0.0, 0.0, 1.0], dtype=torch.float64)
    u = u / u.norm()
    axis = torch.linalg.cross(u, z)
    s, c = float(axis.norm()), float(u @ z)
    if s < 1e-12:
        return torch.eye(3, dtype=torch.float64) if c > 0 else torch.diag(torch.tensor([1.0, -1.0, -1.0]).double())
    k = axis / s
    K = torch.tensor([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]], dtype=torch.float64)
    return torch.eye(3, dtype=torch.float64) + s * K + (1 - c) * (K @ K)


def roi_mask(points: torch.Tensor, cap: CaptureConfig, source: str) -> tuple[torch.Tensor, str]:
    """(inside [N] bool, description) of the region of interest `all`, `sphere` or `box`, in scene coordinates
    (`auto` is resolved to a box by the caller, with `auto_roi`)."""
    x = points.to(torch.float64)
    if cap.roi == "all":
        return torch.ones(len(x), dtype=torch.bool), "region of interest: everything"
    if cap.roi == "sphere":
        if cap.roi_center is None or cap.roi_radius is None:
            raise SceneError(f'{source}: capture.roi = "sphere" needs capture.roi_center and capture.roi_radius.')
        c = torch.tensor(cap.roi_center, dtype=torch.float64)
        return (x - c).norm(
            dim=1
        ) <= cap.roi_radius, f"region of interest: sphere r = {cap.roi_radius:g} at {cap.roi_center}"
    if cap.roi_lower is None or cap.roi_upper is None:
        raise SceneError(f'{source}: capture.roi = "box" needs capture.roi_lower and capture.roi_upper.')
    lo, hi = torch.tensor(cap.roi_lower, dtype=torch.float64), torch.tensor(cap.roi_upper, dtype=torch.float64)
    return ((x >= lo) & (x <= hi)).all(1), "region of interest: box (capture.roi_lower/upper)"


def auto_roi(x: torch.Tensor, percentile: float, source: str = "") -> tuple[torch.Tensor, torch.Tensor]:
    """The object's bounds: a robust core (per-axis bounds at `percentile` % and its complement), grown to
    everything connected to it, so thin extremities (a leaf, a handle, an antenna) that the percentiles clip
    stay part of the object and only what is apart from it is background. Connected: Gaussians on voxels of
    1/48 of the core's extent that touch (26-neighbours, one voxel of slack). Widened by 2 % each side. A
    percentile whose core holds fewer than 10 Gaussians is a SceneError naming it (`source`: "<file>: ")."""
    q = torch.tensor([percentile / 100.0, 1.0 - percentile / 100.0], dtype=torch.float64)
    b = torch.quantile(x[torch.randperm(len(x))[:200_000]] if len(x) > 200_000 else x, q, dim=0)
    core_lo, core_hi = b[0], b[1]
    h = max(float((core_hi - core_lo).max()) / 48.0, 1e-12)
    span = (x.max(0).values - x.min(0).values) / h + 1
    if float(span.prod()) > 64_000_000:  # a scene whose floaters lie far away: voxel the core only
        near = ((x >= core_lo - 0.5 * (core_hi - core_lo)) & (x <= core_hi + 0.5 * (core_hi - core_lo))).all(1)
        if int(near.sum()) < 10:  # the quantiles of each axis alone meet in a box that holds (almost) nothing
            raise SceneError(
                f"{source}capture.percentile = {percentile:g} bounds the automatic region of interest by the "
                f"{percentile:g}th and {100 - percentile:g}th percentiles on every axis, a box that holds "
                f"{int(near.sum())} of {len(x)} Gaussians; use a smaller percentile, e.g. 1 (the default), or set "
                'capture.roi = "box" with roi_lower and roi_upper.'
            )
        return auto_roi_connected(x[near], core_lo, core_hi, h)
    return auto_roi_connected(x, core_lo, core_hi, h)


def auto_roi_connected(x: torch.Tensor, core_lo, core_hi, h: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Bounds of the Gaussians x [N, 3] whose voxels (size h) connect to the core box [core_lo, core_hi]."""
    from scipy import ndimage

    lo = x.min(0).values
    cell = torch.floor((x - lo) / h).to(torch.int64)
    shape = [int(v) + 1 for v in cell.max(0).values]
    occ = np.zeros(shape, dtype=bool)
    occ[cell[:, 0].numpy(), cell[:, 1].numpy(), cell[:, 2].numpy()] = True
    grown = ndimage.binary_dilation(occ, structure=np.ones((3, 3, 3), dtype=bool))
    labels, _ = ndimage.label(grown, structure=np.ones((3, 3, 3), dtype=bool))
    label = torch.from_numpy(labels[cell[:, 0].numpy(), cell[:, 1].numpy(), cell[:, 2].numpy()].astype(np.int64))
    in_core = ((x >= core_lo) & (x <= core_hi)).all(1)
    keep = torch.isin(label, torch.unique(label[in_core])) if bool(in_core.any()) else torch.ones_like(in_core)
    kept = x[keep]
    lo, hi = kept.min(0).values, kept.max(0).values
    pad = 0.02 * (hi - lo) + 1e-9
    return lo - pad, hi + pad


def fit_transform(
    points: torch.Tensor,
    up: torch.Tensor,
    size: float,
    scale: Optional[float] = None,
    rotation: Optional[torch.Tensor] = None,
    offset: Optional[torch.Tensor] = None,
    source: str = "",
) -> SceneTransform:
    """Up onto +z, the longest horizontal principal axis onto x, longest side = size [m], bounding-box
    centre at CENTRE. points: the object's Gaussian means in scene coordinates [N, 3]. Each of `scale`,
    `rotation` [3, 3] (a proper rotation) and `offset` [3] given replaces its automatic value, alone or
    together: the automatic parts are found around the given ones. `source` ("<file>: ") starts its SceneError."""
    x = points.to(torch.float64)
    if len(x) == 0:
        raise SceneError(
            f"{source}the object has no Gaussians left after clean-up, so there is nothing to fit; check the scene "
            "file and the clean-up and ROI keys of [capture] (they may remove everything)."
        )
    if rotation is not None:
        Q = rotation.to(torch.float64)
    else:
        Q = rotation_onto_z(up)
        y = x @ Q.T
        h = y[:, :2] - y[:, :2].mean(0)  # [N, 2] horizontal spread; two Gaussians already have an axis
        evals, evecs = torch.linalg.eigh(h.T @ h)
        a = evecs[:, 1]  # major horizontal axis
        theta = -math.atan2(float(a[1]), float(a[0]))
        c, s = math.cos(theta), math.sin(theta)
        Q = torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64) @ Q
    y = x @ Q.T
    lo, hi = y.min(0).values, y.max(0).values
    longest = float((hi - lo).max())
    if not math.isfinite(longest) or longest <= 0:
        raise SceneError(
            f"{source}the object's {len(x)} Gaussians all lie at one point after clean-up, so it has no size to fit; "
            "check the scene file (a captured object has an extent), or set capture.fit = false to use it as written."
        )
    s_ = float(scale) if scale is not None else size / longest
    if offset is None:
        offset = torch.tensor(CENTRE, dtype=torch.float64) - s_ * 0.5 * (lo + hi)
    return SceneTransform(s_, Q, offset.to(torch.float64))


def config_rotation(cap: CaptureConfig) -> Optional[torch.Tensor]:
    """capture.rotation as a proper rotation [3, 3] float64 (validated within ROTATION_TOLERANCE of one, then
    made exactly orthonormal by the polar decomposition), or None."""
    if cap.rotation is None:
        return None
    R = torch.tensor(cap.rotation, dtype=torch.float64)
    if float((R.T @ R - torch.eye(3, dtype=torch.float64)).abs().max()) < 1e-12:
        return R  # as written (a resolved config's rotation comes back bit for bit)
    U, _, Vh = torch.linalg.svd(R)
    return U @ Vh
