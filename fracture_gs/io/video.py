"""H.264 mp4 and PNG output for uint8 RGB frames (imageio-ffmpeg). Imports neither sim nor render.

H.264 with yuv420p subsamples chroma 2×2, so both frame sides must be even: odd frames are
padded by repeating their last row/column (never resized).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Optional

import numpy as np

MAX_FRAME_SIDE = 16384
"""Pixels: the widest frame libx264 encodes (16,386 fails with "invalid width x height"); cameras and comparison
frames are held to it before a run."""


def ffmpeg():
    """The `imageio_ffmpeg` module with a usable ffmpeg executable, or a one-sentence OutputError naming the
    fix (it is a dependency of fracture-gs, but an environment assembled by hand may lack the package or its
    bundled binary; the PNG frames do not need it)."""
    from ..errors import OutputError

    try:
        import imageio_ffmpeg
    except ImportError as exc:
        raise OutputError(
            "writing MP4 video needs the package imageio-ffmpeg, which is not installed; "
            "run `pip install imageio-ffmpeg` (a dependency of fracture-gs)"
        ) from exc
    try:
        imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as exc:
        raise OutputError(
            "writing MP4 video needs an ffmpeg executable and imageio-ffmpeg found none; reinstall it "
            "(`pip install --force-reinstall imageio-ffmpeg`), install ffmpeg, or set IMAGEIO_FFMPEG_EXE to one"
        ) from exc
    return imageio_ffmpeg


def as_uint8_rgb(img) -> np.ndarray:  # any HxW, HxWx1/3/4, float in [0,1] or uint8 -> HxWx3 uint8
    """A C-contiguous HxWx3 uint8 RGB array from uint8 or float ([0, 1]) numpy/torch images."""
    if hasattr(img, "detach"):  # torch tensor, without importing torch here
        img = img.detach().cpu().numpy()
    a = np.asarray(img)
    if a.dtype != np.uint8:
        a = np.clip(np.rint(a.astype(np.float64) * 255.0), 0, 255).astype(np.uint8)
    if a.ndim == 2:
        a = a[..., None]
    if a.ndim != 3 or a.shape[2] not in (1, 3, 4):
        raise ValueError(f"expected an HxW, HxWx1, HxWx3 or HxWx4 image, got shape {a.shape}")
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    return np.ascontiguousarray(a[..., :3])


def pad_even(img: np.ndarray) -> np.ndarray:  # HxWx3 -> (H+H%2)x(W+W%2)x3
    """Pad an odd height/width by one replicated row/column (bottom/right)."""
    h, w = img.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return img
    return np.ascontiguousarray(np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge"))


class VideoWriter:
    """Streams frames to an H.264 (libx264, yuv420p) mp4; use as a context manager.

    with VideoWriter("out.mp4", fps=24) as vw:
        for frame in frames: vw.write(frame)     # HxWx3 uint8 (or float in [0, 1])

    The first frame fixes the (even-padded) size; later frames must have the same size.
    `quality` is imageio-ffmpeg's 0–10 scale (10 = best).
    """

    def __init__(self, path, fps: float = 24, quality: float = 8):
        self.path = Path(path)
        self.fps = fps
        self.quality = quality
        self.size: Optional[tuple[int, int]] = None  # (W, H) after padding
        self.n_frames = 0
        self._gen = None

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, *_exc):
        self.close()
        return False

    def _open(self, w: int, h: int):
        imageio_ffmpeg = ffmpeg()
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._gen = imageio_ffmpeg.write_frames(
            str(self.path),
            (w, h),
            pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p",
            fps=self.fps,
            codec="libx264",
            quality=self.quality,
            macro_block_size=1,
            output_params=["-movflags", "+faststart"],
        )
        self._gen.send(None)
        self.size = (w, h)

    def write(self, frame) -> None:
        """Append one frame (HxWx3 uint8, or float in [0, 1])."""
        img = pad_even(as_uint8_rgb(frame))
        h, w = img.shape[:2]
        if self._gen is None:
            self._open(w, h)
        elif (w, h) != self.size:
            raise ValueError(
                f"{self.path}: frame {self.n_frames} is {w}x{h} but the video is "
                f"{self.size[0]}x{self.size[1]}; give every frame the same size"
            )
        self._gen.send(img)
        self.n_frames += 1

    def close(self) -> None:
        if self._gen is not None:
            self._gen.close()
            self._gen = None


def write_video(path, frames: Iterable, fps: float = 24, quality: float = 8) -> int:
    """Write all frames to an H.264 mp4; returns the number of frames written."""
    with VideoWriter(path, fps, quality) as vw:
        for f in frames:
            vw.write(f)
    return vw.n_frames


def save_png(path, img) -> None:
    """Save an RGB image (uint8, or float in [0, 1]) as PNG."""
    import cv2

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(os.fspath(path), as_uint8_rgb(img)[..., ::-1].copy()):
        raise OSError(f"{path}: could not write the PNG (check the folder is writable)")


def read_video(path) -> tuple[int, int, int]:
    """(n_frames, H, W) of a video, by decoding every frame (meant for tests)."""
    gen = ffmpeg().read_frames(str(path))
    meta = gen.__next__()
    w, h = meta["size"]
    n = sum(1 for _ in gen)
    return n, int(h), int(w)
