"""--resolution and capture.panel (issue 34, mutation round 12): a resolution override makes a FITTED capture keep
the size asked for (capture.panel = "config"); a built-in scene and a fit = false capture keep panel = "auto" (a run's
config.toml then holds no capture key the scene does not use). The [render] size is set in every case."""

from __future__ import annotations

import pytest
from badinput import capture_doc

from fracture_gs.io.config import apply_overrides, config_from_dict

CASES = [
    ({"extends": "bread"}, "auto"),
    ({"extends": "bread", "capture": {}}, "auto"),
    (capture_doc(fit=False), "auto"),
    (capture_doc(), "config"),
    (capture_doc(fit=True, up="+z"), "config"),
]


@pytest.mark.parametrize("doc, panel", CASES, ids=["builtin", "builtin-empty-capture", "no-fit", "fit", "fit-up"])
@pytest.mark.parametrize("resolution", ["320x240", (200, 150)])
def test_a_resolution_override_pins_the_panel_of_a_fitted_capture_only(doc, panel, resolution):
    """Rule: --resolution sets [render] width and height; only a captured scene with capture.fit = true switches
    capture.panel to "config" (its panel otherwise follows the device), never a built-in scene or fit = false."""
    cfg = config_from_dict(doc, "probe.toml")
    assert cfg.capture.panel == "auto"
    out = apply_overrides(cfg, resolution=resolution)
    w, h = (320, 240) if resolution == "320x240" else resolution
    assert (out.render.width, out.render.height) == (w, h)
    assert out.capture.panel == panel
    assert cfg.capture.panel == "auto"  # the input config is left as it was (a copy is returned)


@pytest.mark.parametrize("doc", [c for c, _ in CASES], ids=[str(i) for i in range(len(CASES))])
def test_without_a_resolution_the_panel_is_left_alone(doc):
    """Rule: other overrides (frames) never touch capture.panel."""
    assert apply_overrides(config_from_dict(doc, "probe.toml"), frames=3).capture.panel == "auto"
