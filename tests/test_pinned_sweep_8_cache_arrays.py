"""Pinned rule of the sweep cache's writer (`fracture_gs.sweep.cache.write_json_atomic`): NaN and ±inf become null
wherever they sit, inside numpy arrays, numpy scalars and torch tensors (of any shape) as well as in plain floats,
so the file is strict JSON and a row of a run with a diverged metric is cached instead of failing the cell; finite
array values and strings are written unchanged.

Unit-level: one small file per test, read back with a reader that refuses NaN and Infinity.
"""

from __future__ import annotations

import json
import math

import numpy as np
import torch

from fracture_gs.sweep import cache


def _strict(path):
    def refuse(token):
        raise AssertionError(f"{path} holds {token}, which is not JSON")

    return json.loads(path.read_text(), parse_constant=refuse)


def test_non_finite_values_inside_arrays_and_tensors_are_written_as_null(tmp_path):
    """A row holding NaN / inf inside a numpy array, a 2-D torch tensor, a 0-d tensor and a numpy float32 scalar is
    written with null in exactly those places and the finite neighbours kept; a string that merely reads 'nan' stays
    a string."""
    path = tmp_path / "cells" / "row.json"
    row = {
        "errors": np.array([0.5, math.nan, 2.0]),
        "span": torch.tensor([[1.0, math.inf], [-math.inf, 4.0]], dtype=torch.float64),
        "peak": torch.tensor(math.nan),
        "f32": np.float32("inf"),
        "ints": np.arange(3),
        "note": "nan",
        "nested": {"list": [np.array([math.nan]), (torch.tensor([2.5]),)]},
    }
    cache.write_json_atomic(path, row)
    assert _strict(path) == {
        "errors": [0.5, None, 2.0],
        "span": [[1.0, None], [None, 4.0]],
        "peak": None,
        "f32": None,
        "ints": [0, 1, 2],
        "note": "nan",
        "nested": {"list": [[None], [[2.5]]]},
    }
    assert [p.name for p in path.parent.iterdir()] == ["row.json"]  # no temporary file left behind
