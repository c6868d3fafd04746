"""Pinned rule of the starter TOML's comments (`capture.starter.commented`), round five: every `key = value`
line is preceded by the documentation of *its own* field: the field of the table's class, and in a
`[[sim.boundaries]]` table the field of the class its `type` names (a region's `lower` is "Box lower corner
[m].", a cuboid's "Box lower corner at `start` [m]."; a sphere's `velocity` is not a cuboid's). A `type` line
in any other table switches nothing, and every table header starts afresh.

The expected class of each table is written here, independently of `starter.TABLES`; the expected text is the
field's docstring in config.py (`field_docs`, pinned elsewhere).
"""

from __future__ import annotations

import re

from fracture_gs.capture import starter
from fracture_gs.config import (
    CameraConfig,
    CaptureConfig,
    ContactConfig,
    CuboidBoundary,
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
from fracture_gs.io.config import config_from_dict, dump_config

OWN = {
    "": SceneConfig,
    "sim": SimConfig,
    "sim.contact": ContactConfig,
    "material": MaterialConfig,
    "material_map": MaterialMapEntry,
    "topology": TopologyConfig,
    "render": RenderConfig,
    "render.camera": CameraConfig,
    "capture": CaptureConfig,
}
BOUNDARY = {"plane": PlaneBoundary, "cuboid": CuboidBoundary, "sphere": SphereBoundary, "region": ParticleRegion}


def comments_by_key(text: str) -> list[tuple[str, str, str, str]]:
    """(table, boundary type or '', key, the comment block right above the key joined into one paragraph)."""
    out, table, kind, block = [], "", "", []
    for line in text.splitlines():
        if line.startswith("# "):
            block.append(line[2:])
            continue
        header = re.match(r"^\[\[?([^\]]+)\]\]?$", line)
        if header:
            table, kind = header.group(1), ""
        elif m := re.match(r'^type = "([a-z]+)"$', line):
            kind = m.group(1) if table == "sim.boundaries" else kind
        if m := re.match(r"^([A-Za-z_][A-Za-z0-9_]*) = ", line):
            out.append((table, kind, m.group(1), " ".join(block)))
        block = []
    return out


def four_boundaries_config():
    return config_from_dict(
        {
            "variants": ["baseline"],
            "sim": {
                "boundaries": [
                    {"type": "plane", "point": [0, 0, 0.1], "normal": [0, 0, 1], "friction": 0.2},
                    {"type": "cuboid", "lower": [0.1, 0.1, 0.1], "upper": [0.2, 0.2, 0.2], "velocity": [0, 0, -1]},
                    {"type": "sphere", "center": [0.5, 0.5, 0.5], "radius": 0.05, "velocity": [1, 0, 0]},
                    {"type": "region", "kind": "impulse", "lower": [0.1, 0.1, 0.1], "upper": [0.2, 0.2, 0.2]},
                ]
            },
            "material_map": [{"label": 1, "E": 1e6}],
        }
    )


def test_every_key_of_a_dumped_config_carries_its_own_fields_documentation():
    """A config with one boundary of each type, a material-map entry and every other table, dumped and
    commented: each key's comment is exactly its own class's field docstring (boundaries by their type), and
    no key of a documented field goes without."""
    docs = starter.field_docs()
    seen = comments_by_key(starter.commented(dump_config(four_boundaries_config())))
    assert {k for _, k, _, _ in seen} >= {"plane", "cuboid", "sphere", "region"}
    checked = 0
    for table, kind, key, comment in seen:
        cls = BOUNDARY[kind] if table == "sim.boundaries" else OWN[table]
        want = docs.get((cls.__name__, key), "")
        assert comment == want, (table, kind, key, comment, want)
        checked += bool(want)
    assert checked >= 100


def test_boundary_keys_shared_by_several_types_are_documented_by_their_own_type():
    """The same key in boundaries of different types reads differently: a region's and a cuboid's corners, a
    sphere's and a cuboid's velocity, a sphere's and a region's end, a plane's and the contact table's friction."""
    seen = {
        (table, kind, key): comment
        for table, kind, key, comment in comments_by_key(starter.commented(dump_config(four_boundaries_config())))
    }
    b = "sim.boundaries"
    assert seen[(b, "region", "lower")] == "Box lower corner [m]."
    assert seen[(b, "cuboid", "lower")] == "Box lower corner at `start` [m]."
    assert seen[(b, "sphere", "velocity")] == "Velocity; the sphere translates with it while active [m/s]."
    assert seen[(b, "cuboid", "velocity")] == "Prescribed node velocity; the box translates with it [m/s]."
    assert seen[(b, "sphere", "end")] == "Time the sphere disappears [s]."
    assert seen[(b, "region", "end")] == "End time [s]."
    assert seen[(b, "plane", "friction")] == "Coulomb coefficient μ for `friction` mode [unitless]."
    assert seen[("sim.contact", "", "friction")] != seen[(b, "plane", "friction")]


def test_a_type_line_outside_the_boundaries_switches_nothing_and_headers_start_afresh():
    """`type = "plane"` in [render] keeps the render table's docs for the keys after it; a [render] table after a
    region keeps nothing of the region; an unknown boundary type falls back to the first boundary class that
    documents the key."""
    docs = starter.field_docs()
    width = docs[("RenderConfig", "width")]
    assert width == "Image width [px] (made even for H.264)."
    text = starter.commented('[render]\ntype = "plane"\nwidth = 640\n')
    assert text.splitlines() == ["[render]", 'type = "plane"', f"# {width}", "width = 640"]
    text = starter.commented('[[sim.boundaries]]\ntype = "region"\nlower = [0, 0, 0]\n\n[render]\nwidth = 640\n')
    seen = {(t, k): c for t, _, k, c in comments_by_key(text)}
    assert seen[("sim.boundaries", "lower")] == "Box lower corner [m]."
    assert seen[("render", "width")] == width
    text = starter.commented('[[sim.boundaries]]\ntype = "wall"\nlower = [0, 0, 0]\nradius = 1.0\n')
    seen = {k: c for _, _, k, c in comments_by_key(text)}
    assert seen["lower"] == "Box lower corner at `start` [m]." and seen["radius"] == "Radius [m] (must be positive)."
