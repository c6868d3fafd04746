"""Gaussian update from F, cameras, splatting backends and the video composer. Takes tensors; never imports sim."""
