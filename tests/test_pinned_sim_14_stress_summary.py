"""The stress provider's report and its plane fit on degenerate input (`sim.providers.stress`):

- `summary()` says `latched: False` and carries no plane before a topology is latched, and `latched: True` with
  the latched plane, time and counts after;
- principal directions that carry no information (all zero: non-finite stresses are reported with a zero
  direction) give a zero mean with agreement 0, in float64 and float32 alike, never NaN — so the plane fit falls
  back to the positions' least-variance axis instead of a NaN normal."""

import torch

from fracture_gs import sim as S
from fracture_gs.sim.providers.stress import StressProvider, mean_direction
from fracture_gs.sim.topology import Topology


def _provider():
    return StressProvider(S.TopologyConfig(provider="stress", min_particles=3, persist_frames=2))


def test_summary_reports_latched_only_once_a_topology_is_held():
    """A fresh provider's summary reads latched False with no latch time or plane; with a topology latched at
    frame 4 (t = 0.4 s, plane x = 0.5 with normal +x, fragments 0, 0, 1) it reads latched True with that time,
    plane and per-fragment counts."""
    p = _provider()
    before = p.summary()
    assert before["provider"] == "stress" and before["latched"] is False
    assert "latch_time" not in before and "normal" not in before
    p.topology = Topology(
        fragment=torch.tensor([0, 0, 1], dtype=torch.int32),
        band=torch.zeros(3, dtype=torch.int32),
        normal=(1.0, 0.0, 0.0),
        point=(0.5, 0.0, 0.0),
        latch_frame=4,
        latch_time=0.4,
    )
    after = p.summary()
    assert after["latched"] is True
    assert after["latch_time"] == 0.4 and after["normal"] == [1.0, 0.0, 0.0] and after["point"] == [0.5, 0.0, 0.0]
    assert after["counts"]["fragment0"] == 2 and after["counts"]["fragment1"] == 1


def test_directions_without_information_give_a_zero_mean_and_no_agreement():
    """Zero directions (float64 and float32): the mean is the zero vector and the agreement 0.0, both finite."""
    for dtype in (torch.float64, torch.float32):
        mean, agreement = mean_direction(torch.zeros(5, 3, dtype=dtype))
        assert mean.tolist() == [0.0, 0.0, 0.0], dtype
        assert agreement == 0.0, dtype


def test_the_plane_fit_falls_back_to_the_least_variance_axis_when_directions_say_nothing():
    """Over-stressed points spread in x and y but flat in z, with zero directions: the fit takes the PCA fallback
    (used_pca) and returns the points' mean and the normal +z."""
    p = _provider()
    g = torch.Generator().manual_seed(3)
    x = torch.rand(40, 3, generator=g, dtype=torch.float64) * torch.tensor([0.4, 0.3, 0.01], dtype=torch.float64)
    point, normal = p.plane(x, torch.zeros(40, 3, dtype=torch.float64))
    assert p.used_pca is True and p.agreement == 0.0
    torch.testing.assert_close(point, x.mean(0))
    assert float(normal[2]) > 0.999
