"""The view record encoded on the frame's device (`viewer.encode_torch`) writes the bytes the numpy reference of the
format writes (`viewer.format.encode_frame` / `encode_epoch`): the quantised centres, the float16 covariances
rounded once to nearest-even (torch's own cast goes through float32 and can round twice), the colours, flags and
clipped fragment ids. So a record made on a GPU reads back exactly like one made on the CPU."""

import numpy as np
import pytest
import torch

from fracture_gs.viewer import format as fmt
from fracture_gs.viewer.encode_torch import epoch_body, frame_packed, half_exact

DEVICES = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])


@pytest.mark.parametrize("device", DEVICES)
def test_half_exact_rounds_once_like_numpy(device):
    """float64 → float16 with one rounding: exact halfway cases between float16 neighbours (ties to even), values
    one float64 ulp beside them (where a float32 step would round twice and land on the wrong neighbour), float16
    subnormals and the format's clip limit all give numpy's float16."""
    ulp = np.float64(2.0**-10)  # float16 spacing in [1, 2)
    ties = 1.0 + ulp * (np.arange(64) + 0.5)  # exactly between two float16 values
    beside = np.concatenate([np.nextafter(ties, 2.0), np.nextafter(ties, 0.0)])
    sub = np.array([2.0**-24, 1.5 * 2.0**-24, 2.5 * 2.0**-24, 3e-6, 6.1e-5, 2.0**-14 * (1 - 2.0**-12)])
    g = np.random.default_rng(0)
    rand = np.concatenate([g.normal(size=4000) * 10.0 ** g.uniform(-8, 4, 4000), [0.0, -0.0, 65000.0, -65000.0]])
    x = np.concatenate([ties, beside, sub, -sub, rand, -ties])
    got = half_exact(torch.from_numpy(x).to(device)).cpu().numpy()
    np.testing.assert_array_equal(got.view(np.uint16), x.astype(np.float16).view(np.uint16))
    # and torch's plain cast really does differ somewhere here (the reason half_exact exists)
    plain = torch.from_numpy(beside).to(device).to(torch.float16).cpu().numpy()
    assert (plain.view(np.uint16) != beside.astype(np.float16).view(np.uint16)).any()


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("n", [0, 1, 7, 3000])
def test_a_packed_frame_is_the_numpy_records_bytes(device, n):
    """Random centres (with NaN and ±inf, which the format writes as 0, and a flat axis whose span is 0) and
    covariances (tiny, huge past the clip, non-finite): header box and body equal `format.encode_frame`'s."""
    g = np.random.default_rng(n)
    means = g.normal(size=(n, 3)).astype(np.float32) * 3
    if n:
        means[:, 2] = 0.25  # a flat axis
    if n > 4:
        means[0, 0], means[1, 1], means[2, 0] = np.nan, np.inf, -np.inf
    cov = (g.normal(size=(n, 3, 3)) * 10.0 ** g.uniform(-9, 2, (n, 1, 1))).astype(np.float32)
    cov = cov @ cov.transpose(0, 2, 1)
    if n > 4:
        cov[3, 0, 0], cov[4, 1, 1] = np.nan, 1e12
    unit = 1e-5
    packed = frame_packed(torch.from_numpy(means).to(device), torch.from_numpy(cov).to(device), unit)
    box, body = packed.cpu().numpy().tobytes()[:24], packed.cpu().numpy().tobytes()[24:]
    ref = fmt.encode_frame(5, 2, 0.25, means, fmt.covariance_triu(cov.astype(np.float64)), unit)
    assert fmt.frame_header(5, 2, 0.25, box) + body == ref


@pytest.mark.parametrize("device", DEVICES)
def test_an_epoch_body_is_the_numpy_records_bytes(device):
    """Colours outside [0, 1] and NaN clip as numpy clips them; fragment ids past int16 clip to 32767; flags pass
    through: the body after the 16-byte header equals `format.encode_epoch`'s."""
    g = np.random.default_rng(3)
    n = 500
    rgb = g.uniform(-0.2, 1.2, (n, 3)).astype(np.float32)
    rgb[0, 0], rgb[1, 1] = np.nan, np.inf
    rgb[2] = [0.5 / 255, 1.5 / 255, 2.5 / 255]  # halfway cases round to even
    flags = g.integers(0, 16, n).astype(np.uint8)
    fragment = g.integers(-1, 70000, n).astype(np.int64)
    body = epoch_body(*(torch.from_numpy(a).to(device) for a in (rgb, flags, fragment)))
    ref = fmt.encode_epoch(4, 9, rgb, flags, fragment)
    assert fmt.epoch_header(4, 9) + body.cpu().numpy().tobytes() == ref


def _reference_record(folder, frames, interior, radius, cov_unit):
    """What `FrameRecorder` writes, by the format's numpy encoders: every frame record, and an epoch record wherever
    the colours, flags (drawn, band, interface from the frame's centres, interior) or fragment ids differ from the
    last epoch's."""
    from fracture_gs.viewer.record import interface_flags

    frames_bytes, epochs_bytes, last, epoch = b"", b"", None, -1
    for k, (out, rgb, drawn) in enumerate(frames):
        means, frag, band = out.means.numpy(), out.fragment.numpy().astype(np.int64), out.band.numpy() != 0
        face = interface_flags(means.astype(np.float32), frag, band, radius)
        flags = drawn.numpy() * fmt.DRAWN + band * fmt.BAND + face * fmt.INTERFACE + interior * fmt.INTERIOR
        body = fmt.encode_epoch(0, 0, rgb.numpy(), flags.astype(np.uint8), frag)[fmt.EPOCH_HEADER :]
        if body != last:
            epoch += 1
            epochs_bytes += fmt.epoch_header(epoch, k) + body
            last = body
        cov6 = fmt.covariance_triu(out.covars.numpy().astype(np.float64))
        frames_bytes += fmt.encode_frame(k, epoch, float(out.time), means, cov6, cov_unit)
    return frames_bytes, epochs_bytes


@pytest.mark.parametrize("device", DEVICES)
def test_the_recorder_writes_the_numpy_references_records(device, tmp_path):
    """A sequence of frames where nothing changes, then only the colours, only what is drawn, the band (a new
    interface), the fragment ids, and back: the recorder's two files are byte for byte the numpy reference's, so an
    epoch starts exactly where one of its parts changed (the change is seen on the device, read with the frame)."""
    from types import SimpleNamespace

    from fracture_gs.config import SceneConfig
    from fracture_gs.io import GaussianSet
    from fracture_gs.viewer.record import FrameRecorder, start_record

    rng = np.random.default_rng(4)
    n = 300
    gs = GaussianSet(
        means=torch.from_numpy(rng.uniform(0, 1, (n, 3))).float(),
        quats=torch.tensor([[1.0, 0, 0, 0]]).repeat(n, 1),
        scales=torch.full((n, 3), 0.02),
        opacities=torch.full((n,), 0.9),
        sh=torch.from_numpy(rng.normal(size=(n, 1, 3))).float(),
    )
    gs.interior = torch.from_numpy(rng.uniform(size=n) < 0.3)
    folder = start_record(tmp_path, SceneConfig(name="r", frames=9), gs, None, ["full"])
    rgb0 = torch.from_numpy(rng.uniform(0, 1, (n, 3))).float()
    rgb1 = rgb0.clone()
    rgb1[5] = 0.25
    drawn0 = torch.ones(n, dtype=torch.bool)
    drawn1 = drawn0.clone()
    drawn1[7] = False
    frag0, band0 = torch.full((n,), -1, dtype=torch.int32), torch.zeros(n, dtype=torch.int32)
    frag1 = (gs.means[:, 0] > 0.5).to(torch.int32)
    band1 = ((gs.means[:, 0] - 0.5).abs() < 0.1).to(torch.int32)
    frag2 = frag1.clone()
    frag2[band1.bool() & (gs.means[:, 1] > 0.5)] = 2
    steps = [  # (fragment, band, rgb, drawn) per frame
        (frag0, band0, rgb0, drawn0), (frag0, band0, rgb0, drawn0), (frag0, band0, rgb1, drawn0),
        (frag0, band0, rgb1, drawn1), (frag1, band1, rgb1, drawn1), (frag1, band1, rgb1, drawn1),
        (frag2, band1, rgb1, drawn1), (frag2, band0, rgb1, drawn1), (frag2, band0, rgb1, drawn1),
        (frag0, band0, rgb0, drawn0),
    ]  # fmt: skip
    covars = gs.covariances()
    frames = []
    for k, (frag, band, rgb, drawn) in enumerate(steps):
        means = gs.means + 0.01 * k * torch.tensor([1.0, -0.5, 0.2])
        out = SimpleNamespace(frame=k, time=0.04 * k, means=means, covars=covars * (1 + 0.1 * k), fragment=frag,
                              band=band)  # fmt: skip
        frames.append((out, rgb, drawn))
    rec = FrameRecorder(folder, "full")
    for out, rgb, drawn in frames:
        on = SimpleNamespace(**{k: v.to(device) if torch.is_tensor(v) else v for k, v in vars(out).items()})
        rec.write(on, rgb.to(device), drawn.to(device))
    rec.close()
    header = __import__("json").loads((folder / fmt.INDEX).read_text())
    want_frames, want_epochs = _reference_record(
        folder, frames, gs.interior.numpy(), float(header["interface_radius"]), float(header["cov_unit"])
    )
    assert (folder / "full.epochs").read_bytes() == want_epochs
    assert (folder / "full.frames").read_bytes() == want_frames
    assert len(want_epochs) == 7 * fmt.epoch_bytes(n)  # frames 0, 2, 3, 4, 6, 7, 9 start epochs
