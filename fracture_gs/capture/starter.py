"""The commented starter TOML of `fracture-gs init scene.ply`: the resolved config of a captured
scene, every key preceded by its documentation (the docstring of its config field), and a header
that lists what was chosen automatically and how to change it."""

from __future__ import annotations

import ast
import datetime
import functools
import inspect
import re
from typing import get_args

from .. import config as config_module
from ..config import (
    BOUNDARY_TYPES,
    CameraConfig,
    CaptureConfig,
    ContactConfig,
    CuboidBoundary,
    LoadKind,
    MaterialConfig,
    MaterialMapEntry,
    ParticleRegion,
    PlaneBoundary,
    RenderConfig,
    SceneConfig,
    SimConfig,
    SphereBoundary,
    TopologyConfig,
)
from ..io.config import dump_config

TABLES = {
    "": (SceneConfig,),
    "sim": (SimConfig,),
    "sim.contact": (ContactConfig,),
    "sim.boundaries": (PlaneBoundary, CuboidBoundary, SphereBoundary, ParticleRegion),
    "material": (MaterialConfig,),
    "material_map": (MaterialMapEntry,),
    "topology": (TopologyConfig,),
    "render": (RenderConfig,),
    "render.camera": (CameraConfig,),
    "capture": (CaptureConfig,),
}


@functools.cache
def field_docs() -> dict[tuple[str, str], str]:
    """(class name, field) → the one-paragraph docstring under the field in config.py."""
    tree = ast.parse(inspect.getsource(config_module))
    docs = {}
    for node in tree.body:
        if not isinstance(node, ast.ClassDef):
            continue
        body = node.body
        for a, b in zip(body, body[1:]):
            if isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name) and isinstance(b, ast.Expr):
                if isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
                    docs[(node.name, a.target.id)] = " ".join(b.value.value.split())
    return docs


def _doc(table: str, key: str, classes: tuple = ()) -> str | None:
    for cls in classes or TABLES.get(table, ()):
        text = field_docs().get((cls.__name__, key))
        if text:
            return text
    return None


def _wrap(text: str, width: int = 98) -> list[str]:
    out, line = [], ""
    for word in text.split():
        if line and len(line) + 1 + len(word) > width:
            out.append(line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    return out + ([line] if line else [])


def commented(toml_text: str) -> str:
    """Every `key = value` line of a dumped config preceded by its field's documentation."""
    out, table, classes = [], "", ()
    for line in toml_text.splitlines():
        header = re.match(r"^\[\[?([^\]]+)\]\]?$", line)
        if header:
            table, classes = header.group(1), ()
        kind = re.match(r'^type = "([a-z]+)"$', line)
        if table == "sim.boundaries" and kind and kind.group(1) in BOUNDARY_TYPES:
            classes = (BOUNDARY_TYPES[kind.group(1)],)  # a boundary's keys documented by its own class
        m = re.match(r"^([A-Za-z_][A-Za-z0-9_]*) = ", line)
        if m and (doc := _doc(table, m.group(1), classes)):
            out += [f"# {w}" for w in _wrap(doc)]
        out.append(line)
    return "\n".join(out) + "\n"


def starter_toml(capture, ply: str) -> str:
    """The starter config of a resolved capture (`capture.scene.Capture`) of the file `ply`."""
    notes = "\n".join(f"#   - {n}" for n in capture.notes)
    loads = ", ".join(f'"{k}"' for k in get_args(LoadKind) if k != "none")
    head = f"""# fracture-gs starter config for {ply}
# written by `fracture-gs init` on {datetime.date.today().isoformat()}: every automatic choice is written out
# below as a plain value. Edit it, then run:  fracture-gs render-sim <this file>
#
# What was chosen:
{notes}
#
# To let fracture-gs choose again: set capture.roi = "auto" (and delete roi_lower/roi_upper),
# delete capture.scale/rotation/offset (the fit; capture.up = "auto", "-y", "+z", ... picks the
# up axis), set sim.grid = "auto", set capture.camera = "auto" or "trainer" (capture.view picks the
# trainer's view), and for another load delete the [[sim.boundaries]] tables and set
# capture.load = {loads}.
"""
    return head + "\n" + commented(dump_config(capture.cfg))
