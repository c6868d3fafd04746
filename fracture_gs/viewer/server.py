"""`fracture-gs view`: a run's recorded frames in the browser, through viser (DESIGN.md "The viewer").

The page is viser's own web client: it draws the splats in the browser (WebGL), so the machine that serves the
run needs no GPU. This module owns the page's controls and what is on screen: a frame slider and play/pause, the
variant shown (or all side by side), colour by fragment, the fracture band and interfaces highlighted, the
capture's static background, the video camera as a preset view, and a button that saves the current view as a PNG.

Frames stream on demand: a change of state (frame, variant, colours) wakes one pusher thread, which reads the
frames now shown from the run folder (`store`), packs them (`panels`, an LRU cache of packed frames) and replaces
the buffers of the splat nodes on screen; requests that arrive while it works collapse into the latest. While the
frame changes (scrubbing, playing) and a frame has more than `preview` drawn Gaussians, a preview of that many
goes first and the whole frame follows once the slider rests.
`max_splats` caps the Gaussians drawn per panel at rest too (every k-th, widened), for a browser that draws
without a GPU: Chromium's own software WebGL (SwiftShader) spends ~20 µs per splat on two cores, and viser
redraws the scene every second, so a frame of 100k Gaussians would keep it busy. A browser with a GPU draws
millions of splats at interactive rates and needs no cap (the default).

Safety: it listens on 127.0.0.1 unless told otherwise, and its HTTP server hands out viser's client files only
(requests are matched against that build folder, `..` refused): nothing of the run folder or elsewhere is served;
frames reach the page over the websocket, read by this process.
"""

from __future__ import annotations

import errno
import math
import socket
import threading
import time
from collections import OrderedDict
from pathlib import Path
from typing import Optional

import numpy as np

from ..errors import ViewError
from . import panels
from .store import RunView

SETTLE_S = 0.25
"""The slider must rest this long before the whole frame replaces a preview [s]."""
CACHE_BYTES = 256 * 2**20
"""Packed frames kept in memory for revisits [bytes]."""


def check_port(host: str, port: int) -> None:
    """Raise ViewError with a one-sentence fix when `port` on `host` cannot be listened on (taken, or an
    address this machine does not have)."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror:
        raise ViewError(f"--host {host} is not an address of this machine; use 127.0.0.1 (the default).") from None
    for family, kind, proto, _, addr in infos[:1]:
        with socket.socket(family, kind, proto) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server's own socket does
            try:
                s.bind(addr)
            except OSError as exc:
                if exc.errno == errno.EADDRINUSE:
                    raise ViewError(
                        f"port {port} on {host} is taken (another viewer or program listens there); "
                        f"pass --port with a free one, e.g. --port {port + 1}."
                    ) from None
                raise ViewError(
                    f"cannot listen on {host}:{port} ({exc.strerror}); pick another --host or --port."
                ) from None


def reach(host: str, port: int) -> str:
    """Who can open the page, as one line for the terminal."""
    if host in ("127.0.0.1", "localhost", "::1"):
        return (
            f"open http://{'localhost' if host == 'localhost' else host}:{port} in a browser on this machine "
            f"(only this machine can reach it; from another one: ssh -L {port}:localhost:{port} THIS_MACHINE)"
        )
    where = "every network interface of this machine" if host in ("0.0.0.0", "::", "") else host
    return (
        f"listening on {where}, port {port}: anyone who can reach this machine on that port can open the page "
        "and see the run (there is no password); the default --host 127.0.0.1 with ssh -L keeps it private"
    )


def camera_at(header: dict, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The video camera at `frame`: eye, target, up and vertical field of view [rad] (the eye turned by
    orbit_degrees·frame/frames about `up` through the target, as the videos' camera)."""
    cam = header["camera"]
    eye, target, up = (np.asarray(cam[k], np.float64) for k in ("eye", "target", "up"))
    axis = up / max(np.linalg.norm(up), 1e-30)
    angle = math.radians(cam.get("orbit_degrees", 0.0) * frame / max(int(header.get("frames", 1)), 1))
    v = eye - target
    v = v * math.cos(angle) + np.cross(axis, v) * math.sin(angle) + axis * (axis @ v) * (1 - math.cos(angle))
    return target + v, target, up, math.radians(cam["fov_deg"])


class Viewer:
    """The viewer of one run: a viser server, its controls and the pusher thread. `close()` stops it."""

    def __init__(
        self, view: RunView, host: str = "127.0.0.1", port: int = 8080, preview: int = 20_000, max_splats: int = 0
    ):
        check_port(host, port)
        try:
            import viser
        except ImportError:
            raise ViewError(
                "fracture-gs view needs viser, which is not installed; install it with "
                "pip install 'fracture-gs[view]' (or pip install 'viser>=1.1,<1.2')."
            ) from None
        self.view, self.header = view, view.header
        self.scale = math.sqrt(float(self.header["cov_unit"]))
        self.server = viser.ViserServer(host=host, port=port, label=f"fracture-gs · {self.header.get('name', '')}")
        if self.server.get_port() != port:  # taken between the check and the bind: viser moved on; we do not
            self.server.stop()
            raise ViewError(f"port {port} on {host} is taken; pass --port with a free one, e.g. --port {port + 1}.")
        self.host, self.port = host, port
        self.preview = int(preview)
        self.cache: OrderedDict = OrderedDict()
        self.cache_bytes = 0
        self.backgrounds: dict[bool, np.ndarray] = {}
        self.handles: dict = {}
        self.pushed: list = []  # (monotonic time, state key, whole?, Gaussians sent) newest last
        self._wake = threading.Condition()
        self._dirty, self._moving, self._pending_full, self._changed_at = True, False, False, time.monotonic()
        self._stop = threading.Event()
        self._playing = False
        self._play_lock = threading.Lock()  # a pause never lands between the player's check and its step
        self._layout()
        self._controls(int(max_splats))
        self.pusher = threading.Thread(target=self._push_loop, name="fgs-view-push", daemon=True)
        self.pusher.start()
        self.player = threading.Thread(target=self._play_loop, name="fgs-view-play", daemon=True)
        self.player.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    # ---------------------------------------------------------------- layout and controls

    def _layout(self) -> None:
        """Scene up axis, the initial (video) camera, and where side-by-side panels go: along the camera's
        right, one object extent and a margin apart."""
        eye, target, up, fov = camera_at(self.header, 0)
        self.server.scene.set_up_direction(tuple(float(u) for u in up / np.linalg.norm(up)))
        cam = self.server.initial_camera
        cam.position, cam.look_at, cam.up, cam.fov = tuple(eye), tuple(target), tuple(up), fov
        forward = (target - eye) / max(np.linalg.norm(target - eye), 1e-30)
        right = np.cross(forward, up)
        right = right / max(np.linalg.norm(right), 1e-30)
        boxes = [self.view.frame(v, k).box for v in self.view.variants for k in (0, self.view.counts[v] - 1)]
        lo, hi = np.min([b[0] for b in boxes], 0), np.max([b[1] for b in boxes], 0)  # every variant, first and last
        extent = max(float((hi - lo) @ np.abs(right)), float(np.linalg.norm(hi - lo)) * 0.5, 1e-6)
        n = len(self.view.variants)
        self.offsets = {v: right * (i - (n - 1) / 2) * extent * 1.15 for i, v in enumerate(self.view.variants)}
        up_unit = up / np.linalg.norm(up)
        self.label_at = (lo + hi) / 2 + up_unit * float((hi - lo) @ np.abs(up_unit)) * 0.65  # above the object

    def _controls(self, max_splats: int) -> None:
        gui, view = self.server.gui, self.view
        notes = "".join(f"\n- {n}" for n in view.notes)
        gui.add_markdown(f"**{self.header.get('name', '')}** · {view.n:,} Gaussians{notes}")
        last = max(view.frames - 1, 1)
        self.frame = gui.add_slider("frame", min=0, max=last, step=1, initial_value=0, disabled=view.frames < 2)
        self.time = gui.add_text("time", initial_value=self._time_text(0), disabled=True)
        self.play = gui.add_button("play", disabled=view.frames < 2)
        self.variant = gui.add_dropdown("variant", options=tuple(view.variants), initial_value=view.variants[0])
        self.side = gui.add_checkbox("side by side", initial_value=False, disabled=len(view.variants) < 2)
        self.color = gui.add_dropdown("colour", options=panels.COLOR_MODES, initial_value="scene")
        self.highlight = gui.add_checkbox("band & interfaces", initial_value=False)
        self.background = gui.add_checkbox(
            "background", initial_value=True, disabled="background_means" not in view.static
        )
        self.budget = gui.add_number("scrub preview", initial_value=self.preview, min=0, step=1000)
        self.max_splats = gui.add_number("max splats", initial_value=max_splats, min=0, step=1000, hint="0: all")
        self.camera = gui.add_button("video camera")
        self.png = gui.add_button("save PNG")

        moving = lambda _: self._changed(moving=True)
        for handle in (self.frame, self.variant, self.side):
            handle.on_update(moving)
        self.side.on_update(lambda _: [self.video_camera(c) for c in self.server.get_clients().values()])
        for handle in (self.color, self.highlight, self.background, self.budget, self.max_splats):
            handle.on_update(lambda _: self._changed(moving=False))
        self.frame.on_update(lambda _: setattr(self.time, "value", self._time_text(int(self.frame.value))))
        self.play.on_click(lambda _: self._toggle_play())
        self.camera.on_click(lambda event: self.video_camera(event.client))
        self.png.on_click(lambda event: self.save_png(event.client))

    def _time_text(self, k: int) -> str:
        dt = float(self.header.get("frame_dt", 0.0))
        return f"t = {k * dt:.3f} s · frame {k} of {self.view.frames - 1}"

    def _toggle_play(self) -> None:
        with self._play_lock:
            self._playing = not self._playing
        self.play.label = "pause" if self._playing else "play"
        if not self._playing:
            self._changed(moving=False)  # the whole frame now that it rests

    def _play_loop(self) -> None:
        period = 1.0 / max(int(self.header.get("fps", 24)), 1)
        while not self._stop.wait(period):
            with self._play_lock:
                if self._playing and self.view.frames > 1:
                    self.frame.value = (int(self.frame.value) + 1) % self.view.frames

    def video_camera(self, client) -> None:
        """Put `client`'s camera where the videos' camera is at the current frame (backed off to take in every
        panel when they are side by side)."""
        if client is None:
            return
        eye, target, up, fov = camera_at(self.header, int(self.frame.value))
        if self.side.value:
            eye = target + (eye - target) * max(1.0, 0.8 * len(self.view.variants))
        with client.atomic():
            client.camera.up_direction = tuple(up)
            client.camera.position, client.camera.look_at, client.camera.fov = tuple(eye), tuple(target), fov

    def save_png(self, client) -> Optional[Path]:
        """The current view of `client` as a PNG: downloaded by its browser and kept in RUN_DIR/views/ (when the
        folder can be written). Returns the file written, or None."""
        if client is None:
            return None
        import imageio.v3 as iio

        h, w = int(client.camera.image_height), int(client.camera.image_width)
        img = client.get_render(height=max(h, 16), width=max(w, 16), transport_format="png", timeout=30)
        data = iio.imwrite("<bytes>", np.asarray(img), extension=".png")
        name = f"{self.header.get('name', 'view')}_{self._shown_label()}_f{int(self.frame.value):04d}"
        folder, path = self.view.run_dir / "views", None
        try:
            folder.mkdir(exist_ok=True)
            path = folder / f"{name}.png"
            i = 1
            while path.exists():
                path, i = folder / f"{name}_{i}.png", i + 1
            path.write_bytes(data)
        except OSError:
            path = None
        client.send_file_download(path.name if path else f"{name}.png", data, save_immediately=True)
        client.add_notification("saved", f"{path}" if path else "downloaded (the run folder is read-only)")
        return path

    def _shown_label(self) -> str:
        return "side_by_side" if self.side.value else str(self.variant.value)

    # ---------------------------------------------------------------- pushing frames

    def _changed(self, moving: bool) -> None:
        with self._wake:
            self._dirty, self._moving = True, moving
            self._changed_at = time.monotonic()
            self._wake.notify()

    def state(self) -> tuple:
        """What should be on screen: (frame, shown variants, colour, highlight, background)."""
        shown = tuple(self.view.variants) if self.side.value else (str(self.variant.value),)
        return (
            int(self.frame.value),
            shown,
            str(self.color.value),
            bool(self.highlight.value),
            bool(self.background.value),
        )

    def _push_loop(self) -> None:
        """Wait for a change (or for a preview's slider to rest), then push; changes made meanwhile collapse."""
        while True:
            with self._wake:
                while not self._stop.is_set() and not self._dirty:
                    if self._pending_full and not self._playing:
                        remaining = SETTLE_S - (time.monotonic() - self._changed_at)
                        if remaining <= 0:
                            break
                        self._wake.wait(remaining)
                    else:
                        self._wake.wait(0.5)
                if self._stop.is_set():
                    return
                dirty, moving = self._dirty, self._moving
                self._dirty = False
            rest = max(int(self.max_splats.value or 0), 0)
            budget = rest
            if dirty and (moving or self._playing):
                budget = min([b for b in (max(int(self.budget.value or 0), 0), rest) if b > 0], default=0)
            try:
                self._pending_full = self.push(self.state(), budget, rest)
            except Exception as exc:  # noqa: BLE001 - the viewer stays up; the terminal says what failed
                print(f"fracture-gs view: could not show the frame: {type(exc).__name__}: {exc}")
                self._pending_full = False

    def _buffer(self, variant: str, frame: int, mode: str, highlight: bool, budget: int) -> np.ndarray:
        key = (variant, frame, mode, highlight, budget)
        if key in self.cache:
            self.cache.move_to_end(key)
            return self.cache[key]
        rec = self.view.frame(variant, frame)
        buf = panels.frame_buffer(rec, self.view.static["opacity"], self.scale, mode, highlight, budget)
        if len(buf) == 0:  # nothing drawn: one transparent Gaussian keeps the node valid
            buf = np.zeros((1, 8), np.uint32)
        self.cache[key] = buf
        self.cache_bytes += buf.nbytes
        while self.cache_bytes > CACHE_BYTES and len(self.cache) > 1:
            self.cache_bytes -= self.cache.popitem(last=False)[1].nbytes
        return buf

    def push(self, state: tuple, budget: int = 0, rest: int = 0) -> bool:
        """Put `state` on screen with at most `budget` Gaussians per panel (0: all); returns whether a fuller
        picture (at most `rest` per panel) should follow once the state rests."""
        frame, shown, mode, highlight, background = state
        partial, sent = False, 0
        wanted: dict[str, tuple] = {}
        for v in shown:
            drawn = int(np.count_nonzero(self.view.frame(v, frame).flags & 1)) if budget or rest else 0
            b = budget if budget and drawn > budget else 0
            partial |= panels.preview_stride(drawn, b) != panels.preview_stride(drawn, rest)
            pos = self.offsets[v] if len(shown) > 1 else np.zeros(3)
            wanted[f"/run/{v}"] = (self._buffer(v, frame, mode, highlight, b), pos)
            sent += len(wanted[f"/run/{v}"][0])
            if background and "background_means" in self.view.static:
                if highlight not in self.backgrounds:  # static: packed once per look (faded or not)
                    self.backgrounds[highlight] = panels.background_buffer(self.view.static, self.scale, highlight)
                wanted[f"/background/{v}"] = (self.backgrounds[highlight], pos)
        with self.server.atomic():
            for name in [n for n in self.handles if n not in wanted]:
                self.handles.pop(name).remove()
            for name, (buf, pos) in wanted.items():
                handle = self.handles.get(name)
                if handle is None:
                    handle = self.server.scene.add_gaussian_splats(
                        name,
                        centers=np.zeros((1, 3), np.float32),
                        covariances=np.zeros((1, 3, 3), np.float32),
                        rgbs=np.zeros((1, 3), np.float32),
                        opacities=np.zeros((1, 1), np.float32),
                        scale=self.scale,
                        position=tuple(pos),
                    )
                    self.handles[name] = handle
                handle.position = tuple(float(p) for p in pos)
                handle.buffer = buf
            self._labels(shown)
        self.pushed.append((time.monotonic(), state, not partial, sent))
        del self.pushed[:-64]
        return partial

    def _labels(self, shown: tuple) -> None:
        """Variant names above the panels when they are side by side."""
        for v in self.view.variants:
            name = f"/labels/{v}"
            if len(shown) > 1 and name not in self.handles:
                self.handles[name] = self.server.scene.add_label(
                    name, v, position=tuple(self.offsets[v] + self.label_at), anchor="bottom-center"
                )
            elif len(shown) == 1 and name in self.handles:
                self.handles.pop(name).remove()

    def close(self) -> None:
        self._stop.set()
        with self._wake:
            self._wake.notify()
        self.pusher.join(timeout=5)
        self.server.stop()


def serve(view: RunView, host: str = "127.0.0.1", port: int = 8080, preview: int = 20_000, max_splats: int = 0) -> int:
    """Serve `view` until Ctrl-C (then exit 0)."""
    from .store import describe

    viewer = Viewer(view, host, port, preview, max_splats)
    print(f"fracture-gs view: {describe(view)}")
    for note in view.notes:
        print(f"fracture-gs view: {note}")
    print(f"fracture-gs view: {reach(host, port)}; Ctrl-C stops it")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("\nfracture-gs view: stopped")
    finally:
        viewer.close()
    return 0
