"""`fracture-gs view`'s server and command line, without a browser: it serves nothing outside viser's own page
files (a request with `..`, an encoded `..`, or an absolute path gets a 404, never a file), a taken port or an
unviewable folder is one sentence with exit 2, it says who can reach it, and its camera preset is the videos'."""

from __future__ import annotations

import http.client
import math
import socket
import subprocess
import sys

import numpy as np
import pytest
from browserutil import free_port
from viewutil import make_run

from fracture_gs import cli
from fracture_gs.errors import ViewError
from fracture_gs.viewer.server import Viewer, camera_at, check_port, reach
from fracture_gs.viewer.store import open_run


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    root = tmp_path_factory.mktemp("served")
    run = make_run(root / "run", frames=2, per_axis=6)
    (root / "secret.txt").write_text("SECRET-OUTSIDE-THE-RUN")
    (run / "inside.txt").write_text("SECRET-INSIDE-THE-RUN")
    return run


@pytest.fixture
def served(run):
    viewer = Viewer(open_run(run), port=free_port())
    yield viewer, run
    viewer.close()


def _get(port: int, path: str) -> tuple[int, bytes]:
    conn = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
    conn.putrequest("GET", path, skip_accept_encoding=True)  # the path as typed: no client-side normalising
    conn.endheaders()
    resp = conn.getresponse()
    body = resp.read()
    conn.close()
    return resp.status, body


def test_nothing_outside_the_page_is_served(served):
    """The page itself is served (200); `..` (plain or percent-encoded, one level or many), absolute paths of
    files on the machine (/etc/passwd, the run's own index.json and a file beside the run) and the run folder's
    files by their names are all refused with a 404 that carries none of their bytes."""
    viewer, run = served
    status, body = _get(viewer.port, "/")
    assert status == 200 and b"<html" in body.lower()
    index = run / "view" / "index.json"
    probes = [
        "/../secret.txt",
        "/../../../../../../etc/passwd",
        "/%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/..%2f..%2f..%2f..%2fetc%2fpasswd",
        "/assets/../../../../secret.txt",
        "/..\\..\\..\\etc\\passwd",
        "//etc/passwd",
        "/etc/passwd",
        "/" + str(index),
        "//" + str(index),
        "/" + str(run.parent / "secret.txt"),
        "/view/index.json",
        "/inside.txt",
        "/view/full.frames",
    ]
    for path in probes:
        status, body = _get(viewer.port, path)
        assert status == 404, (path, status)
        assert b"SECRET" not in body and b"root:" not in body and b"fracture-gs view" not in body, path


def test_a_taken_port_is_one_sentence(run, capsys):
    """A port another program listens on: `check_port` and `fracture-gs view --port N` say so in one sentence
    with a free port to try (exit 2), before viser starts."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ViewError, match=rf"port {port} on 127.0.0.1 is taken .*--port {port + 1}"):
            check_port("127.0.0.1", port)
        assert cli.main(["view", str(run), "--port", str(port)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"port {port} on 127.0.0.1 is taken" in err[0] and "Traceback" not in err[0]


def test_an_unviewable_folder_is_one_line_from_the_cli(tmp_path, capsys):
    """`fracture-gs view` on a folder with no recorded frames: exit 2 and one line that says why."""
    (tmp_path / "metrics.jsonl").write_text("")
    assert cli.main(["view", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no viewable frames" in err[0] and "without the viewer's record" in err[0]


@pytest.mark.parametrize(
    "args, words",
    [
        (["--port", "0"], "not a port"),
        (["--preview", "-1"], "--preview -1"),
        (["--max-splats", "-5"], "--max-splats -5"),
    ],
)
def test_bad_view_flags_are_refused(tmp_path, capsys, args, words):
    """--port outside 1…65535 and a negative --preview are refused in one line (exit 2)."""
    make_run(tmp_path, frames=1, per_axis=4)
    assert cli.main(["view", str(tmp_path), *args]) == 2
    assert words in capsys.readouterr().err


def test_render_sim_view_refuses_a_contradiction_before_the_run(capsys):
    """`render-sim --view --no-view-record` would run the whole simulation and then have nothing to show:
    refused at once (exit 2), before any scene is built."""
    assert cli.main(["render-sim", "bread", "--view", "--no-view-record", "--device", "cpu"]) == 2
    assert "--no-view-record" in capsys.readouterr().err


def test_the_listening_address_says_who_can_reach_it():
    """Loopback: only this machine, and the ssh -L line for a remote one; any other address: who can reach it and
    that there is no password."""
    local = reach("127.0.0.1", 8080)
    assert "only this machine" in local and "ssh -L 8080:localhost:8080" in local
    everyone = reach("0.0.0.0", 9000)
    assert "every network interface" in everyone and "anyone who can reach this machine" in everyone
    assert "no password" in everyone


def test_video_camera_preset_follows_the_orbit():
    """The preset is the videos' camera at the current frame: the eye turned by orbit_degrees·frame/frames about
    `up` through the target (here 90° at the end of a 10-frame run, 45° half way), distance and height kept."""
    header = {
        "frames": 10,
        "camera": {"eye": [1.0, 0.0, 0.5], "target": [0.0, 0.0, 0.0], "up": [0.0, 0.0, 1.0], "fov_deg": 30.0,
                   "orbit_degrees": 90.0},
    }  # fmt: skip
    eye, target, up, fov = camera_at(header, 10)
    assert eye == pytest.approx([0.0, 1.0, 0.5], abs=1e-12) and fov == pytest.approx(math.radians(30))
    eye, *_ = camera_at(header, 5)
    assert eye == pytest.approx([math.sqrt(0.5), math.sqrt(0.5), 0.5], abs=1e-12)
    assert np.asarray(target).tolist() == [0, 0, 0]


@pytest.mark.slow
def test_help_does_not_import_viser():
    """`fracture-gs --help` and `fracture-gs view --help` answer without importing viser: the viewer's library is
    imported only when a viewer starts."""
    code = (
        "import sys; from fracture_gs import cli\n"
        "for a in (['--help'], ['view', '--help']):\n"
        "    assert cli.main(a) == 0\n"
        "print('viser' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "RUN_DIR" in out.stdout and "ssh -L" in out.stdout
    assert out.stdout.splitlines()[-1] == "False"


def test_without_viser_the_viewer_says_how_to_install_it(run, monkeypatch, capsys):
    """viser is an optional extra: without it `fracture-gs view` and `render-sim --view` (before simulating) end
    with one line naming the install command."""
    monkeypatch.setitem(sys.modules, "viser", None)  # `import viser` now raises ImportError
    assert cli.main(["view", str(run), "--port", str(free_port())]) == 2
    assert "pip install 'fracture-gs[view]'" in capsys.readouterr().err
    assert cli.main(["render-sim", "bread", "--view", "--device", "cpu"]) == 2
    err = capsys.readouterr().err
    assert "--view needs viser" in err and "pip install 'fracture-gs[view]'" in err


def test_pause_stops_the_frame_where_it_is_the_moment_it_returns(served):
    """Server side of play/pause: play steps the frame at the run's frame rate; once `pause` has returned the frame
    never moves again (the player's check and step and the toggle share a lock), whenever in a period it lands."""
    import time

    viewer, _ = served
    period = 1.0 / max(int(viewer.header.get("fps", 24)), 1)
    for k in range(6):
        viewer._toggle_play()  # play
        time.sleep(period * (2.3 + 0.37 * k))  # pauses land at different points of the player's period
        before = int(viewer.frame.value)
        viewer._toggle_play()  # pause
        stopped = int(viewer.frame.value)
        assert viewer.play.label == "play"
        time.sleep(period * 3)
        assert int(viewer.frame.value) == stopped, (k, before, stopped)
    viewer._toggle_play()
    deadline = time.monotonic() + 10  # a loaded machine may run the player late
    while int(viewer.frame.value) == stopped and time.monotonic() < deadline:
        time.sleep(period / 4)
    assert int(viewer.frame.value) != stopped  # play again moves it
    viewer._toggle_play()


def test_ctrl_c_stops_the_viewer_with_exit_0(run):
    """Ctrl-C is how a viewer stops, not an interruption of work: once it serves, `fracture-gs view` ends with
    exit 0 and "stopped", not 130 and "interrupted; nothing was written" (main() turned the Ctrl-C the server had
    handled into 130 until the command said it handled it)."""
    import os
    import signal

    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        [sys.executable, "-m", "fracture_gs.cli", "view", str(run), "--port", str(free_port())],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=env,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )
    try:
        for line in proc.stdout:
            if b"Ctrl-C stops it" in line:  # serving: the page is up and the command waits for Ctrl-C
                break
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err.decode()[-2000:]
    assert b"fracture-gs view: stopped" in out and b"interrupted" not in err
