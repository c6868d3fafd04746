"""Chromium for the viewer's tests: Debian's `chromium` driven by playwright (its own browser download is not
used), WebGL drawn on the CPU, and pictures of what the page draws.

Where Xvfb is installed, Chromium runs in a window on a virtual display with WebGL on Mesa's llvmpipe (ANGLE's GL
backend): a CPU rasterizer about 10× faster per splat than Chromium's headless default, SwiftShader, on two cores.
Without Xvfb it runs headless on SwiftShader (slower, the same pictures). The README's test command installs
`chromium` and `xvfb` when they are missing; a machine without chromium fails these tests with the command to run,
it does not skip them.
"""

from __future__ import annotations

import atexit
import io
import os
import shutil
import socket
import subprocess
import time

import numpy as np

HIDE_UI = "body * { visibility: hidden !important; } canvas { visibility: visible !important; }"
"""CSS that leaves only the 3D canvas visible (the control panel and notifications hidden)."""


def chromium_path() -> str:
    """Debian's chromium (or $FRACTURE_GS_CHROMIUM); an AssertionError with the install command otherwise."""
    path = os.environ.get("FRACTURE_GS_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "the viewer's browser tests need chromium: apt-get install -y chromium (README's test command does)"
    return path


_DISPLAY: list = []  # the Xvfb display started for this process, once


def virtual_display():
    """':N' of an Xvfb display started once for this process (stopped at exit), or None without Xvfb."""
    if not _DISPLAY:
        xvfb = shutil.which("Xvfb")
        if xvfb is None or os.environ.get("FRACTURE_GS_HEADLESS"):
            _DISPLAY.append(None)
        else:
            read, write = os.pipe()
            proc = subprocess.Popen(
                [xvfb, "-displayfd", str(write), "-screen", "0", "1600x1200x24", "-nolisten", "tcp"],
                pass_fds=(write,),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            os.close(write)
            with os.fdopen(read) as f:
                number = f.readline().strip()
            atexit.register(proc.terminate)
            _DISPLAY.append(f":{number}" if number else None)
    return _DISPLAY[0]


def launch(playwright):
    """Chromium with WebGL on the CPU, as on a machine without a GPU: llvmpipe on a virtual display, or headless
    SwiftShader."""
    display = virtual_display()
    if display is None:
        return playwright.chromium.launch(
            executable_path=chromium_path(), args=["--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
        )
    return playwright.chromium.launch(
        executable_path=chromium_path(),
        headless=False,
        env={**os.environ, "DISPLAY": display},
        args=["--use-gl=angle", "--use-angle=gl", "--ignore-gpu-blocklist", "--enable-unsafe-swiftshader"],
    )


def renderer(page) -> str:
    """The page's WebGL renderer, e.g. "ANGLE (Mesa/X.org, llvmpipe ...)" or "... SwiftShader ..."."""
    return page.evaluate(
        "() => { const g = document.createElement('canvas').getContext('webgl2');"
        " return g ? g.getParameter(g.getExtension('WEBGL_debug_renderer_info').UNMASKED_RENDERER_WEBGL) : 'none'; }"
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
