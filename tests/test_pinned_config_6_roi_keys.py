"""Pinned rules of the region-of-interest keys (`io.config.validate._check_roi`), round six: which ROI keys each
`capture.roi` uses, and the exact sentence for a key it ignores or lacks.

- `box` uses roi_lower and roi_upper, `sphere` uses roi_center and roi_radius, `auto` and `all` use none;
- a key the chosen roi ignores is refused, and the fix names the roi that *does* use it (a box key → "box", a
  sphere key → "sphere"), whatever roi was chosen;
- a key the chosen roi needs and lacks is refused, pointing at roi = "auto";
- a box must be below its upper corner on every axis (equal is refused), a sphere's radius must be positive.

Each call builds one config from a dict (milliseconds); nothing is simulated.
"""

from __future__ import annotations

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict

VALUES = {"roi_lower": [0.0, 0.0, 0.0], "roi_upper": [1.0, 1.0, 1.0], "roi_center": [0.5, 0.5, 0.5], "roi_radius": 0.5}
USES = {"auto": (), "all": (), "box": ("roi_lower", "roi_upper"), "sphere": ("roi_center", "roi_radius")}
OWNER = {"roi_lower": "box", "roi_upper": "box", "roi_center": "sphere", "roi_radius": "sphere"}


def build(**capture):
    return config_from_dict({"scene": "scene.ply", "variants": ["baseline"], "capture": capture})


def refused(**capture) -> str:
    with pytest.raises(ConfigError) as info:
        build(**capture)
    text = str(info.value)
    assert text.startswith("<dict>: ") and "\n" not in text, text
    return text[len("<dict>: ") :]


@pytest.mark.parametrize("roi", list(USES))
def test_each_roi_accepts_exactly_the_keys_it_uses(roi):
    """roi = auto / all take no ROI key; box takes its two corners, sphere its centre and radius: a config with
    exactly those loads, and keeps the values given."""
    cfg = build(roi=roi, **{k: VALUES[k] for k in USES[roi]})
    assert cfg.capture.roi == roi
    for key in OWNER:
        want = VALUES[key] if key in USES[roi] else None
        got = getattr(cfg.capture, key)
        assert (list(got) if isinstance(got, (tuple, list)) else got) == want, key


@pytest.mark.parametrize(
    "roi, key", [(roi, key) for roi in USES for key in OWNER if key not in USES[roi]], ids=lambda v: str(v)
)
def test_a_key_the_roi_ignores_is_refused_naming_the_roi_that_uses_it(roi, key):
    """An ROI key the chosen roi does not use would be silently ignored: it is refused, and the fix names the
    roi kind the key belongs to (roi_lower / roi_upper → "box", roi_center / roi_radius → "sphere")."""
    given = {k: VALUES[k] for k in USES[roi]}
    msg = refused(roi=roi, **given, **{key: VALUES[key]})
    assert msg == (
        f'capture.{key} is set but capture.roi = {roi!r} ignores it; set capture.roi = "{OWNER[key]}" to use it, '
        f"or remove capture.{key}."
    )


@pytest.mark.parametrize("roi, key", [(roi, key) for roi in ("box", "sphere") for key in USES[roi]])
def test_a_key_the_roi_needs_and_lacks_is_refused(roi, key):
    """roi = box without one of its corners, or sphere without its centre or radius, is refused naming that key;
    the fix is to add it or go back to the automatic region."""
    given = {k: VALUES[k] for k in USES[roi] if k != key}
    msg = refused(roi=roi, **given)
    assert msg == f'capture.roi = {roi!r} needs capture.{key}; add it (scene units), or set capture.roi = "auto".'


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_box_must_be_below_its_upper_corner_on_every_axis(axis):
    """A box whose lower corner equals its upper corner on one axis (zero thickness) is refused; lower below
    upper by a hair on every axis loads."""
    upper = [1.0, 1.0, 1.0]
    upper[axis] = 0.0
    msg = refused(roi="box", roi_lower=[0.0, 0.0, 0.0], roi_upper=upper)
    assert msg.startswith(f"capture.roi_lower = [0.0, 0.0, 0.0] is not below capture.roi_upper = {upper} on every")
    assert msg.endswith("give a box with roi_lower < roi_upper on x, y and z (scene units).")
    upper[axis] = 1e-9
    assert build(roi="box", roi_lower=[0.0, 0.0, 0.0], roi_upper=upper).capture.roi_upper[axis] == 1e-9


@pytest.mark.parametrize("radius", [0.0, -0.5])
def test_a_sphere_radius_must_be_positive(radius):
    """roi = sphere with a zero or negative radius is refused naming capture.roi_radius; a tiny positive radius
    loads."""
    msg = refused(roi="sphere", roi_center=[0.0, 0.0, 0.0], roi_radius=radius)
    assert msg.startswith(f"capture.roi_radius = {radius!r} must be a positive finite number"), msg
    assert build(roi="sphere", roi_center=[0.0, 0.0, 0.0], roi_radius=1e-9).capture.roi_radius == 1e-9
