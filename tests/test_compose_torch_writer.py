"""The comparison video's writer thread (`render_sim.writer.FrameWriter`): frames reach the video in the order they
were handed over, the producer never waits on the encoder beyond the queue's depth, an error on the thread comes
back as one OutputError when the video is closed, and stopping early never hangs."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from fracture_gs.errors import OutputError
from fracture_gs.io.video import read_video
from fracture_gs.render_sim.writer import FrameWriter


class SlowVideo:
    """A stand-in encoder that keeps what it is given, slowly (as ffmpeg does when it is behind), and can fail."""

    def __init__(self, delay: float = 0.0, fail_at: int = -1, error: BaseException = OSError(28, "No space left")):
        self.frames, self.closed, self.delay, self.fail_at, self.error = [], False, delay, fail_at, error

    def write(self, frame) -> None:
        if len(self.frames) == self.fail_at:
            raise self.error
        time.sleep(self.delay)
        self.frames.append(int(frame[0, 0, 0]))

    def close(self) -> None:
        self.closed = True


def frame(k: int) -> np.ndarray:
    return np.full((4, 4, 3), k, np.uint8)


def test_frames_reach_the_video_in_order_and_the_producer_does_not_wait_for_the_encoder(tmp_path):
    """30 frames handed to a slow encoder (5 ms a frame) with room for 30 in the queue: handing them over takes
    far less than encoding them, and the video gets every frame once, in order, then is closed."""
    video = SlowVideo(delay=0.005)
    writer = FrameWriter(tmp_path / "v.mp4", fps=10, depth=30, video=video)
    t0 = time.perf_counter()
    for k in range(30):
        writer.write(frame(k))
    handed = time.perf_counter() - t0
    writer.close()
    assert video.frames == list(range(30)) and video.closed
    assert handed < 0.5 * 30 * 0.005, f"handing 30 frames over took {handed:.3f} s: the producer waited on the encoder"


def test_a_real_video_gets_every_frame(tmp_path):
    """Through ffmpeg: 12 frames of rising grey written by the thread make a 12-frame video whose frames come
    back in that order (their mean level rises)."""
    import imageio.v2 as imageio

    writer = FrameWriter(tmp_path / "v.mp4", fps=10)
    for k in range(12):
        writer.write(np.full((32, 48, 3), 20 * k, np.uint8))
    writer.close()
    assert read_video(tmp_path / "v.mp4") == (12, 32, 48)
    with imageio.get_reader(tmp_path / "v.mp4") as reader:
        levels = [float(np.asarray(f).mean()) for f in reader]
    assert all(abs(level - 20 * k) < 3 for k, level in enumerate(levels)), levels


def test_an_error_on_the_thread_is_one_output_error_at_close_and_nothing_hangs(tmp_path):
    """The encoder fails at its 4th frame (a full disk): the producer still hands over all 50 frames through a
    queue of 2 without blocking for ever (the thread drops what comes after the error), and close() raises one
    OutputError naming the video, how far it got and what to check, chained to the cause."""
    video = SlowVideo(fail_at=3)
    writer = FrameWriter(tmp_path / "v.mp4", fps=10, depth=2, video=video)
    producer = threading.Thread(target=lambda: [writer.write(frame(k)) for k in range(50)], daemon=True)
    producer.start()
    producer.join(timeout=10)
    assert not producer.is_alive(), "the producer hung on a writer that had stopped"
    with pytest.raises(OutputError) as err:
        writer.close()
    message = str(err.value)
    assert str(tmp_path / "v.mp4") in message and "after 3 frames" in message and "No space left" in message
    assert "\n" not in message and isinstance(err.value.__cause__, OSError)
    assert video.frames == [0, 1, 2] and video.closed


def test_an_output_error_of_the_encoder_comes_back_as_it_is(tmp_path):
    """An encoder error that is already the package's one sentence (no ffmpeg: `io.video.ffmpeg`) is raised
    unchanged, not wrapped in a second sentence."""
    missing = OutputError("writing MP4 video needs the package imageio-ffmpeg, which is not installed; run pip")
    writer = FrameWriter(tmp_path / "v.mp4", fps=10, video=SlowVideo(fail_at=0, error=missing))
    writer.write(frame(0))
    with pytest.raises(OutputError) as err:
        writer.close()
    assert err.value is missing


def test_closing_early_or_twice_returns_and_writing_after_close_is_refused(tmp_path):
    """A run stopped before any frame closes its writer at once (the video closed, empty); a second close returns;
    a frame handed over after close is an error, not a frame silently lost."""
    video = SlowVideo()
    writer = FrameWriter(tmp_path / "v.mp4", fps=10, video=video)
    done = threading.Thread(target=writer.close, daemon=True)
    done.start()
    done.join(timeout=10)
    assert not done.is_alive() and video.closed and video.frames == []
    writer.close()
    with pytest.raises(ValueError, match="closed"):
        writer.write(frame(1))


def test_the_live_comparison_stops_at_once_when_the_run_stops_early(tmp_path):
    """The comparison composed beside a variant that stops after 2 of its frames (Ctrl-C, an error) is aborted:
    abort() returns promptly though the frames it waited for never come, and the video holds what was written."""
    from fracture_gs.config import SceneConfig
    from fracture_gs.render_sim.comparison import ComparisonVideo

    cfg = SceneConfig(name="t", frame_dt=0.01)
    rng = np.random.default_rng(0)
    done = [rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(6)]
    growing = [rng.integers(0, 256, (24, 32, 3), dtype=np.uint8) for _ in range(2)]
    live = ComparisonVideo(cfg, ["a", "b"], [done, growing], None, tmp_path, ["ok", "ok"], frames_png=False)
    live.start_live(growing)
    deadline = time.monotonic() + 10
    while live.video.written < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    stopper = threading.Thread(target=live.abort, daemon=True)
    stopper.start()
    stopper.join(timeout=10)
    assert not stopper.is_alive(), "abort() hung"
    assert read_video(tmp_path / "comparison.mp4")[0] == 2
