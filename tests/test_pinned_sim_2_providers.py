"""Fracture providers on a fake simulator (positions, frame, time, Δx only; no Warp): the stress
provider's mean principal direction weighs every particle alike, the oracle's first plane splits
disconnected pieces, a Voronoi snapshot's n_Π is a unit vector, and a follower reads each frame the
leader published from disk once."""

import types

import torch

from fracture_gs.config import TopologyConfig
from fracture_gs.sim.providers.broadcast import FileChannel
from fracture_gs.sim.providers.oracle import OracleProvider
from fracture_gs.sim.providers.stress import mean_direction
from fracture_gs.sim.providers.voronoi import VoronoiProvider
from fracture_gs.sim.topology import Topology


def _fake_sim(x, dx=0.1, frame=0, time=0.0, max_fragments=16):
    return types.SimpleNamespace(
        particles=types.SimpleNamespace(x=x),
        grid=types.SimpleNamespace(dx=dx),
        cfg=types.SimpleNamespace(max_fragments=max_fragments),
        frame=frame,
        time=time,
    )


def _lattice(lo, hi, h):
    axes = [torch.arange(a, b + 1e-9, h, dtype=torch.float64) for a, b in zip(lo, hi)]
    return torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3).float()


def test_mean_direction_weighs_flipped_directions_like_aligned_ones():
    """A principal direction is sign-free: d and −d are the same axis, so flipping a direction to agree with
    the dominant one must not change its weight. x̂ and −(cos 60°, sin 60°, 0) average to the bisector at
    30° (a flipped direction weighted twice would pull the mean to ≈ 40.9°)."""
    c, s = 0.5, 3**0.5 / 2
    d = torch.tensor([[1.0, 0.0, 0.0], [-c, -s, 0.0]], dtype=torch.float64)
    mean, agreement = mean_direction(d)
    mean = mean if mean[0] > 0 else -mean
    want = torch.tensor([3**0.5 / 2, 0.5, 0.0], dtype=torch.float64)
    assert torch.allclose(mean, want, atol=1e-12)
    assert abs(agreement - 3**0.5 / 2) < 1e-12


def test_oracle_first_plane_splits_disconnected_pieces_into_their_own_fragments():
    """With split_components (the default), the first latched plane labels by side and then gives every
    connected piece its own id: two bars 1 m apart cut by x = 0 make four fragments, each holding the
    particles of one half-bar, and the first event lists all four children."""
    a = _lattice((-0.3, 0.0, 0.0), (0.3, 0.1, 0.1), 0.05)
    b = a + torch.tensor([0.0, 1.0, 0.0])
    x = torch.cat([a, b])
    cfg = TopologyConfig(provider="oracle", point=(0.0, 0.0, 0.0), normal=(1.0, 0.0, 0.0))
    t = OracleProvider(cfg)(_fake_sim(x))
    assert t is not None
    frag = t.fragment.long()
    assert int(frag.max()) + 1 == 4
    for piece in (a, b):
        for side in (piece[:, 0] < -1e-6, piece[:, 0] > 1e-6):
            idx = torch.nonzero((x[:, None, :] == piece[side][None]).all(-1).any(1)).flatten()
            assert frag[idx].unique().numel() == 1
    assert len(t.events) == 1 and sorted(t.events[0].children) == [0, 1, 2, 3]


def test_a_voronoi_snapshot_carries_a_unit_normal():
    """Topology.normal is n_Π, a unit vector: the diagnostics project interface openings on it without
    normalising, so a non-unit normal would scale every opening the run reports."""
    x = _lattice((0.0, 0.0, 0.0), (0.4, 0.4, 0.4), 0.05)
    cfg = TopologyConfig(provider="voronoi", cells=4, split_components=False)
    t = VoronoiProvider(cfg)(_fake_sim(x))
    assert t is not None
    assert abs(torch.tensor(t.normal, dtype=torch.float64).norm().item() - 1.0) < 1e-12


def test_a_follower_loads_each_published_frame_once(tmp_path, monkeypatch):
    """A follower polls `up_to` every frame: each frame file the leader wrote is read from disk once and
    kept (re-reading every earlier frame each frame would make a run's I/O grow with frames squared), and
    frames past the one asked for are not read yet."""
    ch = FileChannel(tmp_path, timeout=5.0)
    topo = Topology(fragment=torch.tensor([0, 1]), band=torch.tensor([0, 0]), normal=(1.0, 0.0, 0.0), point=(0, 0, 0))
    for f in range(4):
        ch.publish(f, topo if f == 1 else None)
    loads = []
    real = torch.load
    monkeypatch.setattr(torch, "load", lambda *a, **k: loads.append(a[0]) or real(*a, **k))
    for f in range(3):
        got = ch.up_to(f)
        assert len(got) == (1 if f >= 1 else 0)
    assert sorted(str(p).rsplit("/", 1)[-1] for p in loads) == [f"frame_{f:06d}.pt" for f in range(3)]
