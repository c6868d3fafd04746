"""The on-disk layout of a run's view record (`RUN_DIR/view/`), shared by its writer and its reader.

A run's view record holds what `fracture-gs view` draws, and nothing it would have to simulate or render:

* `index.json`: the header (format name and version, scene, variants, Gaussian count N, frame rate, the video
  camera, the covariance unit), written once before the first frame.
* `static.npz`: what never changes: each Gaussian's opacity, which are interior fill, and the static background
  Gaussians of a captured scene (centres, covariances, colours, opacities).
* `<variant>.frames`: one fixed-size record per frame, appended as the frame is drawn: a 48-byte header
  (magic, frame, epoch, time, the frame's bounding box) and per Gaussian its centre as three uint16 inside that
  box and its covariance's upper triangle as six float16 in units of `cov_unit`: 18 bytes per Gaussian.
* `<variant>.epochs`: one record per topology epoch (a fracture event, or the first frame): per Gaussian its
  colour (uint8 RGB), flags (drawn, fracture band, interface, interior fill) and fragment id (int16): 6 bytes.

Fixed record sizes make frame k's bytes sit at k·R, so the viewer reads one frame without an index, and a run cut
short (Ctrl-C, a crash, a full disk) leaves at most one partial record at the end, which the reader drops.
Quantisation: a centre is kept to 1/65535 of the frame's extent (a 1 m object: 15 µm, far below a pixel of any
view that shows the object whole); float16 covariances are what the browser's splat shader reads anyway.
"""

from __future__ import annotations

import numpy as np

FORMAT = "fracture-gs view"
VERSION = 1
"""The layout version this package writes and reads; a header with another version is refused with why."""

INDEX, STATIC = "index.json", "static.npz"
FRAMES_SUFFIX, EPOCHS_SUFFIX = ".frames", ".epochs"
FRAME_MAGIC, EPOCH_MAGIC = b"FGVF", b"FGVE"
FRAME_HEADER, EPOCH_HEADER = 48, 16
"""Header bytes of a frame record and of an epoch record."""

DRAWN, BAND, INTERFACE, INTERIOR = 1, 2, 4, 8
"""Bits of an epoch's per-Gaussian flags."""

QUANT_STEPS = 65535.0
"""A centre is stored as round(QUANT_STEPS · (x − lo) / (hi − lo)), a uint16."""
F16_CLIP = 65000.0
"""Covariances (in cov_unit) are clipped to ±F16_CLIP before the float16 cast (float16's largest is 65504)."""


def frame_bytes(n: int) -> int:
    """Bytes of one frame record of n Gaussians: header, uint16 centres [n,3], float16 covariances [n,6]."""
    return FRAME_HEADER + 18 * n


def epoch_bytes(n: int) -> int:
    """Bytes of one epoch record of n Gaussians: header, uint8 RGB [n,3], uint8 flags [n], int16 fragment [n]."""
    return EPOCH_HEADER + 6 * n


def covariance_triu(cov):  # [N,3,3] -> [N,6], numpy array or torch tensor
    """The upper triangle (xx, xy, xz, yy, yz, zz) of symmetric 3×3 matrices (numpy or torch: the same indexing)."""
    return cov.reshape(-1, 9)[:, [0, 1, 2, 4, 5, 8]]


def frame_header(frame: int, epoch: int, time: float, box: bytes) -> bytes:
    """A frame record's 48-byte header: magic, frame and epoch (int32), time (float32), the centres' bounding box
    `box` (lo, hi: six float32, 24 bytes), zero padding."""
    head = np.zeros(FRAME_HEADER, np.uint8)
    head[:4] = np.frombuffer(FRAME_MAGIC, np.uint8)
    head[4:12] = np.array([frame, epoch], "<i4").view(np.uint8)
    head[12:16] = np.array([time], "<f4").view(np.uint8)
    head[16:40] = np.frombuffer(box, np.uint8)
    return head.tobytes()


def encode_frame(frame: int, epoch: int, time: float, means: np.ndarray, cov6: np.ndarray, cov_unit: float) -> bytes:
    """One frame record: centres [N,3] quantised to uint16 in their bounding box, covariances [N,6] / cov_unit as
    float16 (clipped to float16's range; a non-finite value becomes 0). The numpy reference of what the recorder
    writes (`encode_torch.frame_packed`, on the frame's device)."""
    means = np.nan_to_num(np.asarray(means, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    lo = means.min(0) if len(means) else np.zeros(3)
    hi = means.max(0) if len(means) else np.zeros(3)
    span = np.where(hi > lo, hi - lo, 1.0)
    q = np.rint((means - lo) / span * QUANT_STEPS).clip(0, QUANT_STEPS).astype("<u2")  # [N,3]
    c = np.nan_to_num(np.asarray(cov6, np.float64) / cov_unit, nan=0.0, posinf=0.0, neginf=0.0)
    c16 = c.clip(-F16_CLIP, F16_CLIP).astype("<f2")  # [N,6]
    box = np.concatenate([lo, hi]).astype("<f4").tobytes()
    return frame_header(frame, epoch, time, box) + q.tobytes() + c16.tobytes()


def decode_frame(buf: bytes, n: int) -> dict:
    """A frame record back: frame, epoch, time, centres [N,3] float32 and covariances [N,6] float16 (× cov_unit).
    Raises ValueError when the bytes are not a frame record."""
    if len(buf) != frame_bytes(n) or buf[:4] != FRAME_MAGIC:
        raise ValueError("not a frame record")
    frame, epoch = np.frombuffer(buf, "<i4", 2, 4)
    time = float(np.frombuffer(buf, "<f4", 1, 12)[0])
    lo, hi = np.frombuffer(buf, "<f4", 6, 16).reshape(2, 3).astype(np.float64)
    q = np.frombuffer(buf, "<u2", 3 * n, FRAME_HEADER).reshape(n, 3)
    cov = np.frombuffer(buf, "<f2", 6 * n, FRAME_HEADER + 6 * n).reshape(n, 6)
    span = np.where(hi > lo, hi - lo, 0.0)
    means = (lo + q * (span / QUANT_STEPS)).astype(np.float32)
    return {"frame": int(frame), "epoch": int(epoch), "time": time, "means": means, "cov": cov, "box": (lo, hi)}


def epoch_header(epoch: int, first_frame: int) -> bytes:
    """An epoch record's 16-byte header: magic, epoch and its first frame (int32), zero padding."""
    head = np.zeros(EPOCH_HEADER, np.uint8)
    head[:4] = np.frombuffer(EPOCH_MAGIC, np.uint8)
    head[4:12] = np.array([epoch, first_frame], "<i4").view(np.uint8)
    return head.tobytes()


def encode_epoch(epoch: int, first_frame: int, rgb: np.ndarray, flags: np.ndarray, fragment: np.ndarray) -> bytes:
    """One epoch record: colours [N,3] in [0,1] to uint8, flags [N] uint8, fragment ids [N] to int16 (clipped). The
    numpy reference of `encode_torch.epoch_body`."""
    rgb8 = np.rint(np.clip(np.nan_to_num(np.asarray(rgb, np.float64)), 0.0, 1.0) * 255).astype(np.uint8)
    frag = np.clip(np.asarray(fragment), -1, 32767).astype("<i2")
    return epoch_header(epoch, first_frame) + rgb8.tobytes() + np.asarray(flags, np.uint8).tobytes() + frag.tobytes()


def decode_epoch(buf: bytes, n: int) -> dict:
    """An epoch record back: epoch, first frame, rgb [N,3] uint8, flags [N] uint8, fragment [N] int16. Raises
    ValueError when the bytes are not an epoch record."""
    if len(buf) != epoch_bytes(n) or buf[:4] != EPOCH_MAGIC:
        raise ValueError("not an epoch record")
    epoch, first = np.frombuffer(buf, "<i4", 2, 4)
    rgb = np.frombuffer(buf, np.uint8, 3 * n, EPOCH_HEADER).reshape(n, 3)
    flags = np.frombuffer(buf, np.uint8, n, EPOCH_HEADER + 3 * n)
    fragment = np.frombuffer(buf, "<i2", n, EPOCH_HEADER + 4 * n)
    return {"epoch": int(epoch), "first_frame": int(first), "rgb": rgb, "flags": flags, "fragment": fragment}
