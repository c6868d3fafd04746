"""Gaussian update from F, cameras, splatting backends and the video composer. Takes tensors; never imports sim."""

from .camera import Camera, from_config, look_at, orbit
from .compose import add_inset, caption, caption_text, grid, interface_region, side_by_side
from .gaussians import deform_covariances, exposed_interior_colors, polar_rotation, sh_colors, visible_mask
from .splat import RenderOutput, project_gaussians, render, render_reference

__all__ = [
    "Camera",
    "look_at",
    "orbit",
    "from_config",
    "polar_rotation",
    "deform_covariances",
    "sh_colors",
    "exposed_interior_colors",
    "visible_mask",
    "RenderOutput",
    "render",
    "render_reference",
    "project_gaussians",
    "caption",
    "side_by_side",
    "grid",
    "add_inset",
    "interface_region",
    "caption_text",
]
