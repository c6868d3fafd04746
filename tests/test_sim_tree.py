"""`fracture_gs.sim` is laid out by role (issue 35, docs/DESIGN.md "sim/ by role"): the two multi-field storages sit
in their own sub-packages and share the stencil math, not each other's code; the top level stays small; the package's
front door keeps its names."""

from __future__ import annotations

from pathlib import Path

from test_imports import import_graph

import fracture_gs.sim as S

SIM = Path(S.__file__).parent
PUBLIC = {
    "layout", "ContactConfig", "CuboidBoundary", "Grid", "MaterialConfig", "OracleProvider", "ParticleRegion",
    "Particles", "PlaneBoundary", "ReplayProvider", "StressProvider", "SimConfig", "SphereBoundary",
    "SimulationDiverged", "SimulationError", "Simulator", "Topology", "TopologyConfig", "fit_grid", "make_provider",
}  # fmt: skip


def reached(graph: dict[str, set[str]], start: set[str]) -> set[str]:
    """Every package module the modules in `start` import, directly or through others (lazy imports included)."""
    seen, todo = set(), list(start)
    while todo:
        for t in graph[todo.pop()]:
            if t in graph and t not in seen:
                seen.add(t)
                todo.append(t)
    return seen


def test_the_box_storage_does_not_import_the_slot_storage():
    """The per-fragment boxes share `sim.stencil` and `sim.physics` with the slot storage but none of `sim.grid`'s
    modules, directly or through another module: the two storages are independent (the stencil math used to live
    in the slot kernels, so the boxes imported them)."""
    graph = import_graph()
    boxes = {m for m in graph if m.startswith("fracture_gs.sim.boxes")}
    assert len(boxes) >= 3, "sim.boxes is a package of its kernels and its host side"
    into_grid = sorted(m for m in reached(graph, boxes) if m.startswith("fracture_gs.sim.grid"))
    assert into_grid == [], f"sim.boxes reaches {into_grid}"
    assert "fracture_gs.sim.stencil" in reached(graph, boxes), "the boxes take the shared stencil math"


def test_the_reach_check_sees_an_indirect_import():
    """The check above can fail: a module reaching another through a third is found."""
    graph = {"a": {"b"}, "b": {"c.x"}, "c.x": set(), "d": {"a"}}
    assert reached(graph, {"a"}) == {"b", "c.x"}


def test_sim_keeps_at_most_twelve_modules_at_its_top_level():
    """sim/ is split by role into sub-packages (grid/, boxes/, physics/, diagnostics/, providers/, diff/): at most
    12 modules (its __init__ included) stay beside them."""
    top = sorted(p.name for p in SIM.glob("*.py"))
    assert len(top) <= 12, top
    assert {p.name for p in SIM.iterdir() if (p / "__init__.py").exists()} >= {
        "grid", "boxes", "physics", "diagnostics", "providers", "diff",
    }  # fmt: skip


def test_the_package_front_door_keeps_its_names():
    """`fracture_gs.sim` exports the names it exported before the split, each bound to a real object, and the
    launch switches' type (`SimOptions`, the one name added)."""
    assert set(S.__all__) == PUBLIC | {"SimOptions"}
    assert all(getattr(S, name) is not None for name in S.__all__)
    assert S.Grid.__module__ == "fracture_gs.sim.grid.fields" and S.layout.__name__ == "fracture_gs.sim.grid.layout"
