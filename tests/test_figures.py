"""`fracture_gs.paper` (figures and accuracy): the table writers (Markdown, CSV, LaTeX), each
figure function on tiny data (a PNG of the expected size), the method figure's slice from a real
two-fragment simulation, and the accuracy cases against their known answers."""

import csv
import io
import json

import cv2
import numpy as np
import pytest
import torch

from fracture_gs import sim as S
from fracture_gs.io.config import load_config
from fracture_gs.paper import accuracy
from fracture_gs.paper.plots import curves_figure, method_figure, method_slice, multiscene_figure, teaser_figure
from fracture_gs.paper.protocol import QUICK, prepare
from fracture_gs.paper.tables import Column, Panel, Table, tex_escape

pytestmark = pytest.mark.usefixtures("one_thread")  # tests/conftest.py: one torch thread


def two_panel_table():
    cols = [
        Column("scene", "Scene", "Scene", "text"),
        Column("mix", "E_mix mean/max", r"$E$ mean/max", "meanmax"),
        Column("open", "Opening/Δx", r"Opening/$\Delta x$", "num"),
        Column("sep", "Sep.", "Sep.", "bool"),
        Column("n", "Latch", "Latch", "int"),
    ]
    rows = [
        {"scene": "Bread_1 & co", "mix": (5.156e-7, 7.637e-6), "open": 10.0091, "sep": True, "n": 10},
        {"scene": "Ficus", "mix": (0.0, 0.0), "open": -0.0182, "sep": False, "n": None},
    ]
    cols_b = [
        Column("method", "Method", "Method", "text"),
        Column("t", "t_c", "$t_c$", "time_pair"),
        Column("pen", "Pen./Δx", "Pen.", "sci"),
    ]
    rows_b = [{"method": "Full", "t": (0.276, None), "pen": 0.026}]
    return Table(
        "table9_test",
        "Table 9: test",
        [Panel(cols, rows), Panel(cols_b, rows_b, "Panel B: contact")],
        "A caption with 50% of σ_R and $x^2$.",
        "tab:test",
        "fracture-gs figures",
        {(0, 0, "open"): True},
    )


def test_table_markdown():
    md = two_panel_table().markdown()
    lines = md.splitlines()
    assert lines[0] == "### Table 9: test"
    assert "| Scene | E_mix mean/max | Opening/Δx | Sep. | Latch |" in lines
    assert "| Bread_1 & co | 5.156e-07/7.637e-06 | **10.009** | Yes | 10 |" in lines
    assert "| Ficus | 0/0 | -0.018 | No | — |" in lines
    assert "*Panel B: contact*" in lines and "| Full | 0.276/— | 2.600e-02 |" in lines
    assert md.rstrip().endswith("Command: `fracture-gs figures`")


def test_table_csv_is_raw_and_per_panel(tmp_path):
    paths = two_panel_table().write(tmp_path)
    names = sorted(p.name for p in paths)
    assert names == ["table9_test.md", "table9_test.tex", "table9_test_A.csv", "table9_test_B.csv"]
    rows = list(csv.DictReader(io.StringIO((tmp_path / "table9_test_A.csv").read_text())))
    assert list(rows[0]) == ["scene", "mix_mean", "mix_max", "open", "sep", "n"]
    assert float(rows[0]["mix_mean"]) == 5.156e-7 and float(rows[0]["open"]) == 10.0091  # full precision
    assert rows[0]["sep"] == "yes" and rows[1]["n"] == ""
    b = list(csv.DictReader(io.StringIO((tmp_path / "table9_test_B.csv").read_text())))
    assert b == [{"method": "Full", "t_0": "0.276", "t_1": "", "pen": "0.026"}]
    one = Table("t", "T", [Panel([Column("a", "a", "a", "num")], [{"a": 1.5}])], "c")
    assert set(one.csv_texts()) == {""}


def test_table_latex():
    tex = two_panel_table().latex()
    assert tex.startswith("\\begin{table*}[t]") and tex.rstrip().endswith("\\end{table*}")
    assert "\\begin{tabular}{llccc}" in tex and "\\toprule" in tex and "\\bottomrule" in tex
    assert "$5.156{\\times}10^{-7}/7.637{\\times}10^{-6}$" in tex
    assert "Bread\\_1 \\& co" in tex and "$\\mathbf{10.009}$" in tex
    assert "\\multicolumn{5}{l}{\\textit{Panel B: contact}}" in tex
    assert "50\\% of $\\sigma$\\_R and $x^2$" in tex  # specials escaped, math kept
    assert "\\label{tab:test}" in tex
    body = tex.split("\\toprule")[1].split("\\bottomrule")[0]
    for line in body.strip().splitlines():
        if line.endswith("\\\\") and not line.startswith("\\multicolumn"):
            assert line.count("&") - line.count("\\&") == 4, line  # every row has the panel's full column count
    assert tex.count("{") == tex.count("}")


def test_tex_escape():
    assert tex_escape("a_b & 5% #1") == "a\\_b \\& 5\\% \\#1"
    assert tex_escape("Δx ≤ 1", math_ok=False) == "$\\Delta$x $\\leq$ 1"
    assert tex_escape("$a_b$ c_d", math_ok=True) == "$a_b$ c\\_d"


def panel(h, w, value):
    img = np.full((h, w, 3), 255, np.uint8)
    img[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4] = value
    return img


def test_teaser_and_multiscene_png(tmp_path):
    frames = [3, 6, 9]
    panels = {v: {f: panel(48, 64, 40 * i + 10 * f) for f in frames} for i, v in enumerate(("baseline", "full"))}
    regions = {3: (32.0, 24.0, 6.0), 6: (32.0, 24.0, 6.0), 9: None}
    img = teaser_figure(panels, frames, 0.04, tmp_path / "teaser.png", regions)
    png = cv2.imread(str(tmp_path / "teaser.png"))
    assert png.shape == img.shape
    bar = 16  # compose's label bar for 64-px-wide cells
    assert png.shape[0] == bar + 4 + 2 * 48 + 4  # column labels, two rows of panels
    assert png.shape[1] >= 3 * 64 + 2 * 4
    np.testing.assert_array_equal(png[..., ::-1], img)  # the PNG holds the composed figure
    # content: the frame-9 panels (no interface region, so no inset) appear whole, baseline above full in the
    # last column; the panels of frames 3 and 6 carry insets, drawn over them
    where = {}
    for v in ("baseline", "full"):
        res = cv2.matchTemplate(img, panels[v][9], cv2.TM_SQDIFF)
        where[v] = np.unravel_index(np.argmin(res), res.shape)
        assert res[where[v]] == 0, f"{v}'s frame 9 is not in the figure"
    assert where["baseline"][0] < where["full"][0] and where["baseline"][1] == where["full"][1]
    assert where["baseline"][1] + 64 >= img.shape[1] - 4, "frame 9 is the last column"
    plain = teaser_figure(panels, frames, 0.04, tmp_path / "plain.png")
    assert np.any(img != plain), "the insets of frames 3 and 6 are drawn"

    scenes = {
        "ficus": {v: panel(60, 48, 90) for v in ("baseline", "stress_zero", "full")},
        "bread": {v: panel(36, 48, 150) for v in ("baseline", "stress_zero", "full")},
    }
    img = multiscene_figure(scenes, tmp_path / "grid.png", {"ficus": (24.0, 30.0, 5.0)}, times={"ficus": "(t = 1 s)"})
    png = cv2.imread(str(tmp_path / "grid.png"))
    assert png.shape == img.shape and png.shape[0] == 16 + 4 + 2 * 60 + 4
    assert (tmp_path / "grid.png").stat().st_size < 1 << 20


@pytest.mark.slow
def test_curves_png(tmp_path):
    t = np.linspace(0.1, 0.9, 20)
    series = {
        s: {
            v: {
                "t": t,
                "opening": t * k,
                "cf": 1e-5 + 0 * t,
                "real": (0 * t if v == "full" else 1e-5 + 0 * t),
                "latch_t": 0.1,
            }
            for k, v in enumerate(("baseline", "stress_zero", "full"))
        }
        for s in ("ficus", "bread")
    }
    curves_figure(series, tmp_path / "curves.png", dpi=50)
    img = cv2.imread(str(tmp_path / "curves.png"))
    assert img.shape == (2 * 140, 450, 3)  # figsize (9, 2.8·rows) × dpi
    ink = (img < 200).any(-1).mean()
    assert 0.01 < ink < 0.6, f"{ink:.3f} of the figure is drawn: blank or filled"
    # the curves are the data: the same figure with full's opening doubled differs, and only in the opening panels
    series["ficus"]["full"]["opening"] = 2 * series["ficus"]["full"]["opening"]
    curves_figure(series, tmp_path / "curves2.png", dpi=50)
    diff = np.any(cv2.imread(str(tmp_path / "curves2.png")) != img, axis=-1)
    assert diff.any(), "changing a series does not change the figure"


def two_blocks(variant="full", storage="auto"):
    """Two blocks 2Δx apart closing at 1 m/s: their fields share support nodes at once."""
    dx = 1 / 16
    xa, vol = accuracy.lattice((0.25, 0.375, 0.375), (0.4375, 0.625, 0.625), dx / 2)
    xb, _ = accuracy.lattice((0.5625, 0.375, 0.375), (0.75, 0.625, 0.625), dx / 2)
    x = torch.cat([xa, xb])
    v = torch.cat([torch.tensor([0.5, 0.0, 0.0]).expand(len(xa), 3), torch.tensor([-0.5, 0.0, 0.0]).expand(len(xb), 3)])
    n = len(x)
    P = S.Particles(
        x=x.float(), v=v.float(), mass=torch.full((n,), 1000 * vol), volume=torch.full((n,), vol), E=1e4, nu=0.3
    )
    cfg = S.SimConfig(dx=dx, grid_shape=(16, 16, 16), gravity=(0, 0, 0), variant=variant, dt=1e-3, grid_storage=storage)
    sim = S.Simulator(cfg, P)
    sim.latch(S.Topology.from_plane(sim.particles.x, (0.5, 0.5, 0.5), (1.0, 0.0, 0.0), 2 * dx))
    for _ in range(5):
        sim.substep()
    return sim


@pytest.mark.parametrize("storage", ["auto", "slots", "boxes"])
def test_method_slice_and_figure(tmp_path, storage):
    """The method figure's slice: nodes of one field, of both, and projected; the impulse on field 1 pushes
    it back. In per-fragment boxes (emptied after every substep) the slice comes from a substep at the end
    state, whose projected nodes are those a slot storage's next substep would project."""
    sim = two_blocks(storage=storage)
    assert sim.boxed == (storage != "slots")
    d = method_slice(sim)
    assert d is not None and d["axes"] == (0, 1)
    cats = set(d["category"].tolist())
    assert {1, 2, 4} <= cats, f"fragment-only nodes and contact-projected nodes expected, got {cats}"
    assert d["n_projected"] > 0
    imp = d["impulse"][d["category"] == 4]
    assert (imp[:, 0] > 0).all(), "the impulse on field 1 (the +x fragment) pushes it back along +n"
    assert np.abs(d["impulse"][d["category"] < 4]).max() == 0
    assert set(np.unique(d["fragment"]).tolist()) == {0, 1} and len(d["px"]) == len(d["fragment"])
    method_figure(d, tmp_path / "method.png", dpi=50)
    img = cv2.imread(str(tmp_path / "method.png"))
    assert img.shape == (230, 400, 3)  # figsize (8, 4.6) × 50 dpi
    ink = (img < 200).any(-1).mean()
    assert 0.02 < ink < 0.8, f"{ink:.3f} of the method figure is drawn: blank or filled"
    d2 = dict(d, impulse=-np.asarray(d["impulse"]))  # the arrows are the data: reversing the impulse redraws them
    method_figure(d2, tmp_path / "method2.png", dpi=50)
    assert np.any(cv2.imread(str(tmp_path / "method2.png")) != img), "the impulse arrows are not drawn from the data"
    assert method_slice(two_blocks("stress_zero")) is None  # a single-field variant has no field sets
    json.dumps({k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in d.items()})  # cacheable


def test_reading_the_box_fields_leaves_the_run_unchanged():
    """`Simulator.box_fields` deposits and updates a substep of its own for the method figure: the run that
    read it goes on bitwise as the one that did not (boxes emptied again, no contact statistics, no escapes
    counted)."""
    a, b = two_blocks(storage="boxes"), two_blocks(storage="boxes")
    stats = a.grid.contact_stats.clone()
    m, p, v, band = a.box_fields()
    assert m.shape == (2, 16, 16, 16) and v.shape == (2, 16, 16, 16, 3) and float(m.sum()) > 0
    assert torch.equal(a.grid.contact_stats, stats) and int(a.counts.sum()) == int(b.counts.sum())
    for _ in range(3):
        a.substep()
        b.substep()
    for name in ("x", "v", "C", "F"):
        assert torch.equal(getattr(a.particles, name), getattr(b.particles, name)), name


def test_quick_protocol_keeps_the_protocol_frames():
    """The quick ficus is compressed 4× in time: same frames, loading 4× faster (times the
    calibrated load scale), switching 4× earlier."""
    base = load_config("exp_table3_ficus")
    q = prepare(base, "quick")
    grip = base.sim.boundaries[-1]
    qgrip = q.cfg.sim.boundaries[-1]
    k = 4 * QUICK["ficus"]["load_scale"]
    assert q.cfg.frames == base.frames and q.cfg.frame_dt == pytest.approx(base.frame_dt / 4)
    assert qgrip.velocity == pytest.approx(tuple(k * v for v in grip.velocity))
    assert qgrip.end == pytest.approx(grip.end / 4)
    assert q.cfg.sim.dx == 1 / 32 and q.cfg.sim.dt == pytest.approx(2 * base.sim.dt)
    b = prepare(load_config("exp_table3_bread"), "quick")
    assert b.cfg.frame_dt == 0.01 and b.cfg.frames == 90 and b.cfg.particles == 4000
    p = prepare(load_config("exp_table3_bread"), "paper")
    assert p.cfg.sim.dx == 1 / 128 and p.cfg.sim.grid_shape == (128, 128, 128) and p.cfg.particles is None


def test_accuracy_helpers(tmp_path):
    t = np.linspace(0, 0.3, 301)
    assert accuracy.period_from_zero_crossings(t, np.cos(2 * np.pi * t / 0.08)) == pytest.approx(0.08, rel=1e-4)
    assert accuracy.pareto_front([(1, 1e-2), (2, 1e-3), (3, 5e-3), (0.5, 1e-1)]) == [3, 0, 1]
    r = [
        accuracy.Result("bar", "dx", 1 / 16, 1e-3, 0.4, 64, 81, 0.02, 0.02, "rel. period error", {}, "x"),
        accuracy.Result("bar", "dt", 1 / 32, 5e-4, 0.2, 512, 161, 0.1, 0.005, "rel. period error", {}, "y"),
    ]
    accuracy.accuracy_table(r, "caption").write(tmp_path)
    rows = list(csv.DictReader(io.StringIO((tmp_path / "accuracy.csv").read_text())))
    assert [x["pareto"] for x in rows] == ["yes", "yes"] and rows[0]["dx"] == "1/16"
    accuracy.pareto_figure(r, tmp_path / "p.png", dpi=50)
    img = cv2.imread(str(tmp_path / "p.png"))
    assert img.shape[:2] == (190, 215)  # figsize (4.3 per case, 3.8) × dpi
    assert 0.01 < (img < 200).any(-1).mean() < 0.6, "the Pareto figure is blank or filled"
    r[1] = accuracy.Result("bar", "dt", 1 / 32, 5e-4, 0.2, 512, 161, 0.1, 0.05, "rel. period error", {}, "y")
    accuracy.pareto_figure(r, tmp_path / "p2.png", dpi=50)
    assert np.any(cv2.imread(str(tmp_path / "p2.png")) != img), "a point's error does not move it in the figure"


@pytest.mark.slow
def test_accuracy_cases_against_known_answers():
    """The bar's first period against 2L/c within 3 % at Δx = 1/16 (0.5 % at 1/32); the spinning
    cube's energy within 0.2 % over a revolution with its angular momentum kept; no
    interpenetration under the contact projection."""
    bar = accuracy.bar_case(1 / 16, 0.4, "cpu")
    assert bar.error < 0.03 and bar.extra["exact"] == pytest.approx(0.1)
    assert accuracy.bar_case(1 / 32, 0.4, "cpu").error < 0.006
    spin = accuracy.spin_case(1 / 16, 0.8, "cpu")
    assert spin.error < 2e-3 and spin.extra["angular_momentum_drift"] < 1e-4
    rc = accuracy.recontact_case(1 / 32, 0.8, "cpu")
    assert rc.extra["penetration_dx"] < 0.1 and rc.extra["first_contact_time"] is not None


def test_partial_rerun_keeps_the_figures_an_earlier_call_made(tmp_path):
    """`fracture-gs figures --only bench` after a full call: the README keeps every figure whose image is still
    in the folder (as it keeps the tables), a figure this call made again replaces the earlier entry, an entry
    whose image is gone is dropped, and the order stays Figure 1, 2, ...; a kept figure names the call that
    made it, not this one."""
    from fracture_gs.paper.readme import merged_figures

    for name in ("fig_teaser.png", "fig_method.png"):
        (tmp_path / name).write_bytes(b"png")
    earlier = [
        {"title": "Figure 1: teaser", "path": "fig_teaser.png", "caption": "old"},
        {"title": "Figure 3: method", "path": "fig_method.png", "caption": "old"},
        {"title": "Figure 2: gone", "path": "fig_gone.png", "caption": "old"},
    ]
    meta = {"command": "fracture-gs figures --out X"}
    (tmp_path / "summary.json").write_text(json.dumps({"figure_entries": earlier, "meta": meta}))
    now = [{"title": "Figure 3: method", "path": str(tmp_path / "fig_method.png"), "caption": "new"}]
    merged = merged_figures(tmp_path, now)
    assert [f["title"] for f in merged] == ["Figure 1: teaser", "Figure 3: method"]
    assert merged[0]["path"] == str(tmp_path / "fig_teaser.png") and merged[1]["caption"] == "new"
    assert merged[0]["command"] == "fracture-gs figures --out X" and "command" not in merged[1]
    assert merged_figures(tmp_path / "nowhere", now) == now  # no earlier summary: this call's only


@pytest.mark.slow
def test_fragment_rows_press_the_shattered_ficus_with_momentum_conserved():
    """The figures' K table (`paper.fragments`): per K the timing of both branches, and the pieces pressed into
    each other: contact fires on more nodes for more pieces, the projection conserves momentum (relative
    residual ≤ 1e-6), no piece ends inside another (fragment-aware penetration ≤ 1 Δx)."""
    from fracture_gs.paper.fragments import fragment_rows

    rows, particles, n = fragment_rows("cpu", 3000, 32, Ks=(2, 16), steps=2, warmup=1, trials=1, frames=5)
    assert [r["K"] for r in rows] == [2, 16] and particles == 3000 and n == 32
    for r in rows:
        assert r["shared_ms"] > 0 and r["ff_ms"] > 0 and r["ff_mib"] > 0
        assert r["residual"] <= 1e-6 and r["penetration"] <= 1.0, r
    assert rows[1]["contact_nodes"] > rows[0]["contact_nodes"] > 0, rows
