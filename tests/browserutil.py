"""Headless Chromium for the viewer's tests: Debian's `chromium` driven by playwright (its own browser download
is not used), WebGL drawn in software (SwiftShader), and pictures of what the page draws.

The README's test command installs `chromium` when it is missing; a machine without it fails these tests with
the command to run, it does not skip them.
"""

from __future__ import annotations

import io
import os
import shutil
import socket
import time

import numpy as np

HIDE_UI = "body * { visibility: hidden !important; } canvas { visibility: visible !important; }"
"""CSS that leaves only the 3D canvas visible (the control panel and notifications hidden)."""


def chromium_path() -> str:
    """Debian's chromium (or $FRACTURE_GS_CHROMIUM); an AssertionError with the install command otherwise."""
    path = os.environ.get("FRACTURE_GS_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "the viewer's browser tests need chromium: apt-get install -y chromium (README's test command does)"
    return path


def launch(playwright):
    """Headless Chromium with WebGL in software, as on a machine without a GPU."""
    return playwright.chromium.launch(
        executable_path=chromium_path(), args=["--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
    )


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def picture(page) -> np.ndarray:  # -> [H,W,3] uint8
    """What the 3D canvas shows now (the page's controls hidden for the shot)."""
    import imageio.v3 as iio

    style = page.add_style_tag(content=HIDE_UI)
    try:
        png = page.screenshot()
    finally:
        style.evaluate("e => e.remove()")
    return iio.imread(io.BytesIO(png))[..., :3]


def ink(img: np.ndarray) -> np.ndarray:  # [H,W,3] -> [H,W] bool
    """Pixels that are not the white background."""
    return (255 - img.astype(np.int16)).max(-1) > 40


def settled(page, viewer, state, timeout: float = 60.0) -> np.ndarray:
    """The picture once `viewer` has pushed the whole frame of `state` (or any whole frame, state None) and two
    shots in a row agree (the browser's depth sort done)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        last = viewer.pushed[-1] if viewer.pushed else None
        if last is not None and last[2] and (state is None or last[1] == state):
            break
        time.sleep(0.05)
    else:
        raise AssertionError(f"the viewer never pushed {state}; it pushed {viewer.pushed[-3:]}")
    before = picture(page)
    while time.monotonic() < end:
        time.sleep(0.2)
        now = picture(page)
        if ink(now).any() and np.abs(now.astype(np.int16) - before).max() <= 2:
            return now
        before = now
    raise AssertionError("the picture never settled")
