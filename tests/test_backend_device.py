"""A renderer that cannot draw on the run's device is refused before the run prepares anything: gsplat draws CUDA
tensors only, the Warp rasterizer CPU tensors only. (Before, the run simulated its first frame and then failed.)"""

import pytest

from fracture_gs import cli
from fracture_gs.errors import RenderError
from fracture_gs.render.splat import check_backend


@pytest.mark.parametrize(
    "backend, device, refused",
    [
        ("gsplat", "cpu", True),
        ("warp", "cuda:0", True),
        ("warp", "cuda", True),
        ("gsplat", "cuda:1", False),
        ("warp", "cpu", False),
        ("torch", "cpu", False),
        ("torch", "cuda:0", False),
        ("auto", "cpu", False),
        ("auto", "cuda:0", False),
    ],
)
def test_each_backend_draws_only_where_it_can(backend, device, refused):
    """gsplat needs CUDA, warp needs the CPU; torch and auto draw anywhere. A refusal is one sentence naming the
    key, the device and what to use instead."""
    if not refused:
        check_backend(backend, device)
        return
    with pytest.raises(RenderError) as err:
        check_backend(backend, device)
    text = str(err.value)
    assert f"render.backend = '{backend}'" in text and device in text and "use 'auto'" in text
    assert "\n" not in text


def test_render_sim_refuses_gsplat_on_the_cpu_before_the_scene(tmp_path, capsys):
    """`render.backend = "gsplat"` with `--device cpu`: exit 2 with one line, and the run folder holds nothing (no
    config.toml is written, no frame simulated)."""
    cfg = tmp_path / "gsplat_cpu.toml"
    cfg.write_text('extends = "bread"\n\n[render]\nbackend = "gsplat"\n')
    out = tmp_path / "out"
    assert cli.main(["render-sim", str(cfg), "--device", "cpu", "--frames", "2", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "render.backend = 'gsplat'" in err and "cpu" in err and len(err.splitlines()) == 1
    assert not (out / "config.toml").exists()
