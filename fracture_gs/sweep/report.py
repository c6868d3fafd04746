"""A finished sweep's rows → sweep.md, sweep.tex, sweep.csv, sweep.json and sweep_pareto.png.

sweep.md / sweep.tex: one panel per cell kind (accuracy: the columns of `bench --accuracy`'s table
plus the Pareto flag per case; scene: render-sim's summary columns), a status column in each
(`ok`, `failed: <sentence>`, `missing: ...`). sweep.csv: every row, every key (the union, in
first-seen order), raw values at full precision. sweep.json: the rows plus where the sweep came
from. sweep_pareto.png: error against wall time of the accuracy cells that ran (one point per
spec-table label, `fracture_gs.paper.accuracy.pareto_figure`), written when matplotlib is there.
"""

from __future__ import annotations

import csv
import datetime
import io
import json
from pathlib import Path

from ..paper.accuracy import FLOOR, MEASURE_COLUMNS, Result, pareto_figure, pareto_front
from ..paper.tables import Column, Panel, Table

_ACCURACY_COLUMNS = [
    Column("id", "Cell", "Cell", "text"),
    Column("case", "Case", "Case", "text"),
    Column("labels", "Sweep", "Sweep", "text"),
    Column("dx_text", "Δx", r"$\Delta x$", "text"),
    *MEASURE_COLUMNS,
    Column("pareto", "Pareto", "Pareto", "bool"),
    Column("status_text", "Status", "Status", "text"),
]

_SCENE_COLUMNS = [
    Column("id", "Cell", "Cell", "text"),
    Column("config", "Config", "Config", "text"),
    Column("variant", "Variant", "Variant", "text"),
    Column("cells", "Cells", "Cells", "int"),
    Column("step", "Step", "Step", "text"),
    Column("set", "Overrides", "Overrides", "text"),
    Column("seed", "Seed", "Seed", "int"),
    Column("particles", "Particles", "Particles", "int"),
    Column("latch_frame", "Latch frame", "Latch frame", "int"),
    Column("opening", "Opening/Δx", r"Opening/$\Delta x$", "num"),
    Column("reapproach", "Re-approach", "Re-approach", "num"),
    Column("stringing", "Stringing", "Stringing", "num"),
    Column("mixing_realized_mean", "E_mix real", r"$E_\mathrm{mix}$ real", "sci"),
    Column("penetration_max", "Pen./Δx", r"Pen./$\Delta x$", "num"),
    Column("fragments", "Fragments", "Fragments", "int"),
    Column("substeps", "Substeps", "Substeps", "int"),
    Column("wall_s", "Wall (s)", "Wall (s)", "num"),
    Column("status_text", "Status", "Status", "text"),
]


def _status_text(row: dict) -> str:
    status = row.get("status", "missing")
    return status if status == "ok" else f"{status}: {row.get('message', '')}".replace("|", "/")


def accuracy_results(rows: list[dict]) -> list:
    """The finished accuracy rows as `fracture_gs.paper.accuracy.Result`s, one per label."""
    out = []
    for r in rows:
        if r.get("kind") != "accuracy" or r.get("status") != "ok":
            continue
        for label in str(r.get("labels", "grid")).split("+"):
            out.append(
                Result(
                    case=r["case"],
                    sweep=label,
                    dx=1.0 / r["cells"],
                    dt=r["dt"],
                    cfl=r["cfl"],
                    particles=r["particles"],
                    substeps=r["substeps"],
                    wall_s=r["wall_s"],
                    error=r["error"],
                    unit=r["unit"],
                    extra={},
                    detail=r.get("detail", ""),
                )
            )
    return out


def _pareto_flags(rows: list[dict]) -> dict:
    """id → on the (wall time, error) Pareto front of its case (finished accuracy rows only)."""
    flags = {}
    ok = [r for r in rows if r.get("kind") == "accuracy" and r.get("status") == "ok"]
    for case in dict.fromkeys(r["case"] for r in ok):
        rs = [r for r in ok if r["case"] == case]
        front = set(pareto_front([(r["wall_s"], max(r["error"], FLOOR)) for r in rs]))
        flags.update({r["id"]: i in front for i, r in enumerate(rs)})
    return flags


def sweep_table(title: str, rows: list[dict], caption: str, command: str) -> Table:
    """The md/tex table: an accuracy panel and a scene panel (whichever kinds the sweep has)."""
    flags = _pareto_flags(rows)
    panels = []
    acc = [
        {
            **r,
            "dx_text": f"1/{r['cells']}",
            "pareto": flags.get(r["id"]) if r.get("status") == "ok" else None,
            "status_text": _status_text(r),
        }
        for r in rows
        if r.get("kind") == "accuracy"
    ]
    if acc:
        panels.append(Panel(_ACCURACY_COLUMNS, acc, "Accuracy cells (case × Δx × CFL)"))
    scene = [{**r, "status_text": _status_text(r)} for r in rows if r.get("kind") == "scene"]
    if scene:
        panels.append(Panel(_SCENE_COLUMNS, scene, "Scene cells (config × variant × settings × seed)"))
    return Table("sweep", title, panels, caption, "tab:sweep", command)


def csv_text(rows: list[dict]) -> str:
    """Every row with the union of the keys (first-seen order); nested values as JSON."""
    keys: dict[str, None] = {}
    for r in rows:
        keys.update(dict.fromkeys(k for k in r if k not in ("traceback", "extra")))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(keys))
    for r in rows:
        vals = []
        for k in keys:
            v = r.get(k)
            if v is None:
                vals.append("")
            elif isinstance(v, bool):
                vals.append("yes" if v else "no")
            elif isinstance(v, float):
                vals.append(repr(v))
            elif isinstance(v, (dict, list)):
                vals.append(json.dumps(v))
            else:
                vals.append(str(v))
        w.writerow(vals)
    return buf.getvalue()


def write_outputs(out_dir, spec, rows: list[dict], world_size: int, command: str = "") -> list[str]:
    """Write the tables, the JSON and the plot; returns the file names written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    count = {s: sum(1 for r in rows if r.get("status") == s) for s in ("ok", "failed", "missing")}
    devices = sorted({f"{r['device']}: {r.get('device_name', '')}" for r in rows if r.get("device")})
    date = datetime.date.today().isoformat()
    caption = (
        f"{len(rows)} cells from {spec.source}: {count['ok']} ok, {count['failed']} failed, "
        f"{count['missing']} missing; world size {world_size}; devices {', '.join(devices) or 'none'}; {date}. "
        "Wall (s) is the timed run of each cell (accuracy: after warm-up, as bench --accuracy; scene: the "
        "simulation with its per-frame diagnostics, as render-sim's summary)."
    )
    table = sweep_table(spec.title, rows, caption, command)
    (out / "sweep.md").write_text(table.markdown())
    (out / "sweep.tex").write_text(table.latex())
    (out / "sweep.csv").write_text(csv_text(rows))
    payload = {
        "spec": str(spec.path),
        "title": spec.title,
        "command": command,
        "date": date,
        "world_size": world_size,
        "devices": devices,
        "counts": count,
        "rows": rows,
    }
    (out / "sweep.json").write_text(json.dumps(payload, indent=1, default=str))
    files = ["sweep.md", "sweep.tex", "sweep.csv", "sweep.json"]
    results = accuracy_results(rows)
    if results:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            return files
        pareto_figure(results, out / "sweep_pareto.png", title=f"{spec.title} — {', '.join(devices)}")
        files.append("sweep_pareto.png")
    return files
