"""Hand-written bug campaign, config validation (`io.config.validate`): rules the earlier tests left open.

- A material label maps to one set of parameters: a second [[material_map]] entry for the same label would
  silently override (or be overridden by) the first, so it is refused, naming the second entry.

Each case builds one config from a dict (milliseconds); nothing is simulated."""

import pytest

from fracture_gs.errors import ConfigError
from fracture_gs.io.config import config_from_dict

BASE = {"variants": ["baseline"]}


@pytest.mark.parametrize("labels, second", [((1, 1), 1), ((0, 2, 0), 2), ((3, 4, 5, 4), 3)])
def test_a_material_label_given_twice_is_refused_at_its_second_entry(labels, second):
    """Labels listed in order; the first repeat (entry `second`) is named, whatever entries lie between."""
    entries = [{"label": label, "E": 1e6 * (i + 1)} for i, label in enumerate(labels)]
    with pytest.raises(ConfigError, match=rf"material_map\[{second}\]\.label = {labels[second]} appears twice"):
        config_from_dict({**BASE, "material_map": entries})


def test_distinct_material_labels_are_accepted():
    """Three different labels: a valid map (the duplicate rule counts labels, not entries)."""
    cfg = config_from_dict({**BASE, "material_map": [{"label": k, "E": 1e6} for k in (0, 1, 2)]})
    assert [e.label for e in cfg.material_map] == [0, 1, 2]
