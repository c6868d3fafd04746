"""A follower waits for its leader's frame for one hour by default (`sim.providers.broadcast`), in a thread
(`MemoryChannel`) and in another process (`FileChannel`) alike, and the error when it gives up names that wait
in whole seconds: a leader stuck in a long frame must not be abandoned early by default."""

import threading

import pytest

from fracture_gs.sim.providers.broadcast import FileChannel, MemoryChannel


class _NeverReady:
    """A condition variable whose wait always runs out (records the timeout it was given)."""

    def __init__(self):
        self.timeouts = []
        self._lock = threading.Lock()

    def __enter__(self):
        return self._lock.__enter__()

    def __exit__(self, *exc):
        return self._lock.__exit__(*exc)

    def wait_for(self, predicate, timeout=None):
        self.timeouts.append(timeout)
        return predicate()


def test_a_memory_follower_waits_one_hour_by_default_and_says_so():
    """MemoryChannel(): the wait for frame 3 is given 3600 s, and running out raises 'within 3600 s'."""
    ch = MemoryChannel()
    ch._changed = _NeverReady()
    with pytest.raises(TimeoutError, match=r"^the leading variant did not reach frame 3 within 3600 s$"):
        ch.up_to(3)
    assert ch._changed.timeouts == [3600.0]


def test_both_channels_share_the_one_hour_default(tmp_path):
    """FileChannel and MemoryChannel give up after the same default wait, 3600 s."""
    assert FileChannel(tmp_path / "ch").timeout == 3600.0
    assert MemoryChannel().timeout == 3600.0
