"""Content checks for rendered images: the object's pixels are where the camera projects its Gaussians, the
background everywhere far from them (a blank, shifted or mirrored frame fails)."""

import math

import cv2
import numpy as np
import torch


def _project(cam, points):
    uv, z = cam.project(torch.as_tensor(points, dtype=cam.viewmat.dtype))
    return uv.double().numpy(), z.double().numpy()


def projected_pixels(cam, points) -> np.ndarray:  # -> [M, 2] integer (col, row) of the points in front, on screen
    uv, z = _project(cam, points)
    px = np.floor(uv).astype(np.int64)
    ok = (z > 0) & (px[:, 0] >= 0) & (px[:, 0] < cam.width) & (px[:, 1] >= 0) & (px[:, 1] < cam.height)
    return px[ok]


def footprint(cam, points, sigma, margin_px: float = 2.0) -> np.ndarray:  # -> [H, W] bool
    """Pixels a Gaussian of world-space standard deviation `sigma` ([N] or a float) at each point can touch: a
    disc of 3·√((σ f / z)² + 0.3) px (the rasterizer's 3σ cut-off of the 2D covariance with its 0.3 px² blur),
    widened by 30 % for the off-axis stretch of the projection, plus `margin_px`."""
    uv, z = _project(cam, points)
    f = float(cam.K[0, 0])
    sigma = np.broadcast_to(np.asarray(sigma, dtype=np.float64), z.shape)
    mask = np.zeros((cam.height, cam.width), np.uint8)
    for (u, v), depth, s in zip(uv, z, sigma):
        if depth <= 0:
            continue
        r = 1.3 * 3.0 * math.sqrt((s * f / depth) ** 2 + 0.3) + margin_px
        if -r <= u <= cam.width + r and -r <= v <= cam.height + r:
            cv2.circle(mask, (int(round(u)), int(round(v))), int(math.ceil(r)), 1, -1)
    return mask.astype(bool)


def check_object_where_projected(img, cam, points, sigma, background, near_frac=0.9, tol=0):
    """`img` ([H, W, 3], uint8 or float in [0, 1]) shows the object at the projection of `points` ([N, 3],
    Gaussians of world-space standard deviation `sigma`) through `cam`: at least `near_frac` of the pixels a point
    projects into differ from `background` (RGB in [0, 1]) by more than `tol`/255, and every pixel outside all the
    Gaussians' footprints is the background within `tol`/255 (tol absorbs video compression). Returns (fraction of
    projected pixels covered, number of background pixels checked)."""
    img = np.asarray(img)
    img = img.astype(np.float64) / 255.0 if img.dtype == np.uint8 else img.astype(np.float64)
    diff = np.abs(img - np.asarray(background, dtype=np.float64)).max(-1)  # [H, W]
    px = projected_pixels(cam, points)
    assert len(px) > 0, "no point projects into the image"
    covered = float((diff[px[:, 1], px[:, 0]] > tol / 255 + 1e-6).mean())
    assert covered >= near_frac, f"only {covered:.2f} of the projected pixels show the object"
    far = ~footprint(cam, points, sigma)
    assert far.sum() > 0.1 * far.size, "the object fills the frame: no background to check"
    worst = float(diff[far].max())
    assert worst <= tol / 255 + 1e-6, (
        f"a pixel outside the object's footprint differs from the background by {worst * 255:.1f}/255"
    )
    return covered, int(far.sum())
