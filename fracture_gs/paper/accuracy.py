"""Speed against error: Δt and Δx sweeps of the solver on cases with known answers.

    fracture-gs bench --accuracy --quick                      # CPU, a few minutes
    fracture-gs bench --accuracy --device cuda:0 --out runs/accuracy_gpu
    fracture-gs bench --accuracy [--quick]            # the same, through the bench entry point

Cases (each with an analytic or exact answer; MLS-MPM as the solver runs it, variant `baseline`
unless stated):

* ``bar`` — free–free elastic bar, longitudinal vibration. Length L = 0.5 m (its ends on grid
  nodes for every Δx of the sweeps), square section 0.0625 m, E = 1e4 Pa, ρ = 100 kg/m³ and
  **ν = 0**: with no Poisson coupling the 1D wave equation is exact for any section (no thin-bar
  or lateral-inertia approximation), c = √(E/ρ)
  = 10 m/s and the first mode's period is T = 2L/c = 0.1 s. Initial velocity
  v_x = V cos(π s/L) (s the rest coordinate along the bar, V = 0.02 m/s, strain amplitude 0.2 %);
  the modal velocity q(t) = Σ m v_x cos(π s/L) / Σ m cos²(π s/L) is sampled 100 times per period
  over two periods, and the period comes from its zero crossings. Error = |T_meas − T| / T.
* ``spin`` — elastic cube (0.2 m, E = 1e4 Pa, ν = 0.3, ρ = 100) spinning freely about z at
  ω = 5 rad/s (rim speed 0.5 m/s), no gravity, for one revolution (2π/ω = 1.26 s), started with
  the APIC affine velocity of the rigid rotation (C = skew ω). The exact answer conserves the
  total energy E = Σ ½ m (|v|² + Δx²/4 ‖C‖²) + Σ V⁰ ψ(F) (APIC kinetic energy with the quadratic
  B-spline inertia Δx²/4, fixed-corotated ψ = μ‖F − R‖² + λ/2 (J − 1)²). Error = relative energy
  drift |E(T) − E(0)| / E(0); the angular momentum drift is reported too. Measured here: the drift
  is ≈ 7e-4 at every Δt and Δx of the quick sweep and falls ≈ 10× with E = 1e5, i.e. it is the
  decay of the breathing mode that the unstretched start excites (its energy ∝ ρ²ω⁴a⁵/E), not
  the transfers' dissipation of the rigid rotation.
* ``recontact`` — two blocks (mass ratio ≈ 2.2:1, E = 2e5 Pa, ρ = 1000) closing at 0.6 m/s with
  tangential sliding, no gravity, variant `full` (FractureFields' contact projection), oracle
  interface, 0.2 s. The exact answer is zero interpenetration. Error = the Table 4 Panel B
  penetration (largest overlap along n of the two fragments near the interface), in metres
  (and in Δx); 0 is plotted at the floor 1e-7 m.

Sweeps: Δx at a fixed CFL number (Δt = CFL·Δx/c, c the P-wave speed plus the largest initial
speed), and Δt (CFL 0.1–0.8) at a fixed Δx. Wall time per setting is the whole run after a
warm-up (kernels compiled), synchronized on CUDA. Outputs: ``accuracy.{md,csv,tex}``,
``accuracy_pareto.png`` (error against wall time, Pareto front per case), ``accuracy.json``.
"""

from __future__ import annotations

import datetime
import json
import math
import platform
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from .. import sim as S
from ..runtime import ensure_warp
from .tables import Column, Panel, Table

FLOOR = 1e-7  # plotted in place of an exact zero error (log axes)


def lattice(lo, hi, spacing):
    """Particles at the centres of a regular lattice filling [lo, hi]: x [N,3] float64, volume."""
    axes = [torch.arange(a + spacing / 2, b - 1e-12, spacing, dtype=torch.float64) for a, b in zip(lo, hi)]
    x = torch.stack(torch.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    return x, spacing**3


def _sync(device):
    if str(device).startswith("cuda"):
        torch.cuda.synchronize()


def p_wave(E, nu, rho):
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    return math.sqrt((lam + 2 * mu) / rho)


def _sim(x, vol, rho, E, nu, v, dx, dt, device, variant="baseline", provider=None, margin=0.3):
    n = x.shape[0]
    P = S.Particles(
        x=x.float(), v=v.float(), mass=torch.full((n,), rho * vol), volume=torch.full((n,), vol), E=E, nu=nu
    )
    cfg = S.SimConfig(dx=dx, dt=dt, grid="auto", grid_margin=margin, gravity=(0.0, 0.0, 0.0), variant=variant)
    return S.Simulator(cfg, P, device=device, provider=provider)


# --------------------------------------------------------------------------------------------
# cases


@dataclass
class Result:
    case: str
    sweep: str  # "dx" or "dt"
    dx: float
    dt: float
    cfl: float
    particles: int
    substeps: int
    wall_s: float
    error: float
    unit: str
    extra: dict
    detail: str = ""

    def row(self) -> dict:
        return {
            "case": self.case,
            "sweep": self.sweep,
            "dx": f"1/{round(1 / self.dx)}",
            "dt": self.dt,
            "cfl": self.cfl,
            "particles": self.particles,
            "substeps": self.substeps,
            "wall_s": self.wall_s,
            "error": self.error,
            "unit": self.unit,
            "detail": self.detail,
            **self.extra,
        }


BAR = dict(L=0.5, a=0.0625, E=1e4, rho=100.0, V=0.02, periods=2.0)


def bar_case(dx: float, cfl: float, device: str, sweep: str = "dx") -> Result:
    """Free–free bar, first longitudinal mode; error = relative period error."""
    L, a, E, rho, V = BAR["L"], BAR["a"], BAR["E"], BAR["rho"], BAR["V"]
    c = math.sqrt(E / rho)
    T = 2 * L / c
    x0 = 0.25  # a multiple of every swept Δx (1/16 … 1/128, 1/24 … 1/96), as is L
    x, vol = lattice((x0, 0.5 - a / 2, 0.5 - a / 2), (x0 + L, 0.5 + a / 2, 0.5 + a / 2), dx / 2)
    s = x[:, 0] - x0
    phi = torch.cos(math.pi * s / L)
    v = torch.zeros_like(x)
    v[:, 0] = V * phi
    dt = cfl * dx / (c + V)
    sample = max(1, round(T / 100 / dt))
    steps = int(math.ceil(BAR["periods"] * T / dt))
    _sync(device)
    t0 = time.perf_counter()
    sim = _sim(x, vol, rho, E, 0.0, v, dx, dt, device)
    m = sim.particles.mass.double()
    w = m * phi.to(m.device).double()
    denom = float((m * phi.to(m.device).double() ** 2).sum())
    ts, qs = [0.0], [float((w * sim.particles.v[:, 0].double()).sum()) / denom]
    for i in range(1, steps + 1):
        sim.substep(dt)
        if i % sample == 0:
            ts.append(i * dt)
            qs.append((w * sim.particles.v[:, 0].double()).sum() / denom)
    qs = [qs[0]] + torch.stack(qs[1:]).cpu().tolist()
    _sync(device)
    wall = time.perf_counter() - t0
    period = period_from_zero_crossings(np.asarray(ts), np.asarray(qs))
    err = abs(period - T) / T if math.isfinite(period) else float("inf")
    amp = float(np.max(np.abs(qs[len(qs) // 2 :])) / abs(qs[0]))
    return Result(
        "bar",
        sweep,
        dx,
        dt,
        cfl,
        len(x),
        steps,
        wall,
        err,
        "rel. period error",
        {"measured": period, "exact": T, "amplitude_ratio": amp},
        f"T = {period:.5f} s (exact {T:.5f}), amplitude after {BAR['periods']:g} periods {amp:.3f}",
    )


def period_from_zero_crossings(t: np.ndarray, q: np.ndarray) -> float:
    """Period of an oscillating signal from the spacing of its zero crossings (linear interpolation)."""
    sgn = np.sign(q)
    idx = np.nonzero(sgn[:-1] * sgn[1:] < 0)[0]
    if len(idx) < 2:
        return float("nan")
    tz = t[idx] - q[idx] * (t[idx + 1] - t[idx]) / (q[idx + 1] - q[idx])
    return float(2.0 * np.mean(np.diff(tz)))


SPIN = dict(a=0.2, E=1e4, nu=0.3, rho=100.0, omega=5.0, T=2 * math.pi / 5.0)


def elastic_energy(F: torch.Tensor, E: float, nu: float, vol: torch.Tensor) -> float:
    """Σ V⁰ ψ(F), fixed-corotated ψ = μ‖F − R‖²_F + λ/2 (J − 1)² (float64)."""
    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    F = F.double()
    U, _, Vh = torch.linalg.svd(F)
    R = U @ Vh
    flip = torch.linalg.det(R) < 0
    if bool(flip.any()):
        U = U.clone()
        U[flip, :, 2] *= -1
        R = U @ Vh
    J = torch.linalg.det(F)
    psi = mu * ((F - R) ** 2).sum((1, 2)) + 0.5 * lam * (J - 1) ** 2
    return float((vol.double() * psi).sum())


def spin_state(sim) -> tuple[float, float, torch.Tensor]:
    """(APIC kinetic energy, elastic energy, angular momentum about the cube's centre)."""
    P = sim.particles
    m, v = P.mass.double(), P.v.double()
    D = sim.grid.dx**2 / 4  # quadratic B-spline inertia
    ke = float(0.5 * (m * ((v**2).sum(1) + D * (P.C.double() ** 2).sum((1, 2)))).sum())
    ee = elastic_energy(P.F, SPIN["E"], SPIN["nu"], P.volume)
    c = torch.tensor([0.5, 0.5, 0.5], dtype=torch.float64, device=P.x.device)
    C = P.C.double()
    axial = torch.stack([C[:, 2, 1] - C[:, 1, 2], C[:, 0, 2] - C[:, 2, 0], C[:, 1, 0] - C[:, 0, 1]], 1)
    L = (m[:, None] * (torch.linalg.cross(P.x.double() - c, v, dim=1) + D * axial)).sum(0)  # APIC angular momentum
    return ke, ee, L


def spin_case(dx: float, cfl: float, device: str, sweep: str = "dx") -> Result:
    """Free spinning elastic cube; error = relative drift of kinetic + elastic energy."""
    a, E, nu, rho, w = SPIN["a"], SPIN["E"], SPIN["nu"], SPIN["rho"], SPIN["omega"]
    x, vol = lattice((0.5 - a / 2,) * 3, (0.5 + a / 2,) * 3, dx / 2)
    r = x - 0.5
    v = torch.stack([-w * r[:, 1], w * r[:, 0], torch.zeros(len(x), dtype=x.dtype)], 1)
    vmax = w * a / math.sqrt(2)
    dt = cfl * dx / (p_wave(E, nu, rho) + vmax)
    steps = int(math.ceil(SPIN["T"] / dt))
    _sync(device)
    t0 = time.perf_counter()
    sim = _sim(x, vol, rho, E, nu, v, dx, dt, device, margin=0.6)
    # APIC: the initial affine velocity of a rigid rotation is C = skew(ω) (exactly representable)
    Wm = torch.tensor([[0.0, -w, 0.0], [w, 0.0, 0.0], [0.0, 0.0, 0.0]], device=sim.particles.C.device)
    sim.particles.C.copy_(Wm.expand_as(sim.particles.C))
    ke0, ee0, L0 = spin_state(sim)
    for _ in range(steps):
        sim.substep(dt)
    ke1, ee1, L1 = spin_state(sim)
    _sync(device)
    wall = time.perf_counter() - t0
    e0, e1 = ke0 + ee0, ke1 + ee1
    drift = abs(e1 - e0) / e0
    dL = float((L1 - L0).norm() / L0.norm())
    return Result(
        "spin",
        sweep,
        dx,
        dt,
        cfl,
        len(x),
        steps,
        wall,
        drift,
        "rel. energy drift",
        {"energy_0": e0, "energy_T": e1, "angular_momentum_drift": dL},
        f"E {e0:.5f} → {e1:.5f} J, |ΔL|/|L| = {dL:.1e}",
    )


RECONTACT = dict(speed=0.6, E=2e5, rho=1000.0, frames=40, frame_dt=0.005)


def recontact_case(dx: float, cfl: float, device: str, sweep: str = "dx") -> Result:
    """Fragment re-contact under FractureFields; error = max penetration [m] (exact answer 0)."""
    speed, E, rho = RECONTACT["speed"], RECONTACT["E"], RECONTACT["rho"]
    xa, vol = lattice((0.28, 0.42, 0.42), (0.44, 0.58, 0.58), dx / 2)
    xb, _ = lattice((0.52, 0.45, 0.45), (0.72, 0.55, 0.55), dx / 2)
    ma, mb = len(xa), len(xb)
    va, vb = speed * mb / (ma + mb), -speed * ma / (ma + mb)  # zero total momentum
    x = torch.cat([xa, xb])
    v = torch.cat(
        [
            torch.tensor([va, va / 4, 0.0], dtype=x.dtype).expand_as(xa),
            torch.tensor([vb, vb / 4, 0.0], dtype=x.dtype).expand_as(xb),
        ]
    )
    front = float(xa[:, 0].max())
    contact_x = front + va * (float(xb[:, 0].min()) - front) / speed
    topo = S.TopologyConfig(
        provider="oracle",
        point=(contact_x, 0.5, 0.5),
        normal=(1.0, 0.0, 0.0),
        latch_frame=0,
        band_width=4.0,
        pair_radius=6.0,
    )
    dt = cfl * dx / (p_wave(E, 0.3, rho) + speed)
    frame_dt = RECONTACT["frame_dt"]
    _sync(device)
    t0 = time.perf_counter()
    sim = _sim(x, vol, rho, E, 0.3, v, dx, dt, device, variant="full", provider=S.make_provider(topo))
    sim.cfg.dt = dt
    tracker = sim.diagnostics_tracker()
    for _ in range(RECONTACT["frames"]):
        sim.advance(frame_dt)
    _sync(device)
    wall = time.perf_counter() - t0
    rows = [r for r in tracker.history if "penetration" in r]
    pen = max(r["penetration"] for r in rows)  # in Δx
    last = rows[-1]
    return Result(
        "recontact",
        sweep,
        dx,
        sim.dt,
        cfl,
        len(x),
        sim.substeps,
        wall,
        pen * dx,
        "max penetration [m]",
        {
            "penetration_dx": pen,
            "first_contact_time": last.get("first_contact_time"),
            "identity_crossing": max(r["identity_crossing"] for r in rows),
            "rel_normal_velocity_after": last.get("rel_normal_velocity_after"),
            "cp_momentum_residual": last.get("cp_momentum_residual"),
        },
        f"{pen:.3f} Δx, crossing {max(r['identity_crossing'] for r in rows)}, v_rel,n+ "
        f"{last.get('rel_normal_velocity_after') or 0:.1e} m/s",
    )


CASES = {"bar": bar_case, "spin": spin_case, "recontact": recontact_case}

SWEEPS = {
    # case: (Δx list at fixed CFL, fixed CFL, Δx of the Δt sweep, CFL list)
    "quick": {
        "bar": ([1 / 16, 1 / 24, 1 / 32, 1 / 48], 0.4, 1 / 32, [0.1, 0.2, 0.4, 0.8]),
        "spin": ([1 / 16, 1 / 24, 1 / 32], 0.4, 1 / 24, [0.1, 0.2, 0.4, 0.8]),
        "recontact": ([1 / 32, 1 / 48], 0.4, 1 / 32, [0.1, 0.2, 0.4, 0.8]),
    },
    "full": {
        "bar": ([1 / 16, 1 / 24, 1 / 32, 1 / 48, 1 / 64, 1 / 96, 1 / 128], 0.4, 1 / 64, [0.05, 0.1, 0.2, 0.4, 0.8]),
        "spin": ([1 / 16, 1 / 24, 1 / 32, 1 / 48, 1 / 64, 1 / 96], 0.4, 1 / 48, [0.05, 0.1, 0.2, 0.4, 0.8]),
        "recontact": ([1 / 32, 1 / 48, 1 / 64, 1 / 96, 1 / 128], 0.4, 1 / 64, [0.05, 0.1, 0.2, 0.4, 0.8]),
    },
}


def sweep(case: str, spec, device: str, progress=True) -> list[Result]:
    dxs, cfl0, dx0, cfls = spec
    out = []
    fn = CASES[case]
    for dx in dxs:
        out.append(fn(dx, cfl0, device, "dx"))
        if progress:
            _print(out[-1])
    for cfl in cfls:
        if abs(cfl - cfl0) < 1e-12 and any(abs(r.dx - dx0) < 1e-12 for r in out):
            r = next(r for r in out if abs(r.dx - dx0) < 1e-12)
            out.append(Result(**{**r.__dict__, "sweep": "dt"}))
        else:
            out.append(fn(dx0, cfl, device, "dt"))
        if progress:
            _print(out[-1])
    return out


def _print(r: Result):
    print(
        f"  {r.case:<10s} {r.sweep:<3s} dx=1/{round(1 / r.dx):<4d} CFL {r.cfl:<5g} dt={r.dt:.3g} "
        f"substeps={r.substeps:<6d} "
        f"particles={r.particles:<7d} {r.wall_s:8.2f} s  error={r.error:.3e} ({r.unit})",
        flush=True,
    )


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of the points not dominated in (time, error), sorted by time."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def pareto_figure(results: list[Result], path, title: str = "", dpi: int = 100) -> None:
    """Error against wall time per case (log–log), Δx sweep (circles) and Δt sweep (triangles),
    each point labelled, the Pareto front as a line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import ticker

    class _PlainLog(ticker.LogFormatter):
        """Log-axis labels as plain numbers (0.3, 2, 10); which ticks get one is LogFormatter's choice."""

        def _num_to_string(self, x, _vmin, _vmax):
            return f"{x:g}"

    cases = list(dict.fromkeys(r.case for r in results))
    fig, axes = plt.subplots(1, len(cases), figsize=(4.3 * len(cases), 3.8), dpi=dpi, squeeze=False)
    for ax, case in zip(axes[0], cases):
        rs = [r for r in results if r.case == case]
        pts = [(r.wall_s, max(r.error, FLOOR)) for r in rs]
        for r, (t, e) in zip(rs, pts):
            ax.scatter(
                t,
                e,
                marker="o" if r.sweep == "dx" else "^",
                s=30,
                c="#1f78b4" if r.sweep == "dx" else "#e31a1c",
                zorder=3,
            )
            lab = f"1/{round(1 / r.dx)}" if r.sweep == "dx" else f"C{r.cfl:g}"
            # Δx labels above right, Δt labels below right: a setting both sweeps share stays readable
            ax.annotate(lab, (t, e), textcoords="offset points", xytext=(4, 3 if r.sweep == "dx" else -9), fontsize=7)
        front = pareto_front(pts)
        ax.plot([pts[i][0] for i in front], [pts[i][1] for i in front], "k-", lw=0.8, alpha=0.7, zorder=2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        # plain numbers on the time axis ("0.3", "2"): the default "2×10⁰" labels collide within a decade
        ax.xaxis.set_major_formatter(_PlainLog(labelOnlyBase=False))
        ax.xaxis.set_minor_formatter(_PlainLog(labelOnlyBase=False, minor_thresholds=(0.8, 0.3)))
        ax.set_xlabel("wall time per run [s]")
        ax.set_ylabel(rs[0].unit)
        ax.set_title(case, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    axes[0][0].scatter([], [], marker="o", c="#1f78b4", label="Δx sweep (label 1/n)")
    axes[0][0].scatter([], [], marker="^", c="#e31a1c", label="Δt sweep (label CFL)")
    axes[0][0].plot([], [], "k-", lw=0.8, label="Pareto front")
    axes[0][0].legend(fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


MEASURE_COLUMNS = [
    Column("cfl", "CFL", "CFL", "num"),
    Column("dt", "Δt (s)", r"$\Delta t$ (s)", "sci"),
    Column("particles", "Particles", "Particles", "int"),
    Column("substeps", "Substeps", "Substeps", "int"),
    Column("wall_s", "Wall (s)", "Wall (s)", "num"),
    Column("error", "Error", "Error", "sci"),
    Column("unit", "Error measure", "Error measure", "text"),
]
"""What one setting measured (the columns `accuracy_table` and the sweep's tables share)."""


def accuracy_table(results: list[Result], caption: str, command: str = "") -> Table:
    cols = [
        Column("case", "Case", "Case", "text"),
        Column("sweep", "Sweep", "Sweep", "text"),
        Column("dx", "Δx", r"$\Delta x$", "text"),
        *MEASURE_COLUMNS,
        Column("detail", "Detail", "Detail", "text"),
        Column("pareto", "Pareto", "Pareto", "bool"),
    ]
    rows = []
    for case in dict.fromkeys(r.case for r in results):
        rs = [r for r in results if r.case == case]
        front = set(pareto_front([(r.wall_s, max(r.error, FLOOR)) for r in rs]))
        for i, r in enumerate(rs):
            rows.append({**r.row(), "pareto": i in front})
    return Table(
        "accuracy", "Speed against error (Δt and Δx sweeps)", [Panel(cols, rows)], caption, "tab:accuracy", command
    )


def warmup(device: str) -> None:
    """Compile and load the kernels once so that no setting's wall time includes it."""
    bar_case(1 / 16, 0.8, device)
    recontact_case(1 / 32, 0.8, device)


def run_accuracy(
    device: str = "cpu", out_dir="runs/accuracy", quick: bool = False, cases=None, progress: bool = True
) -> dict:
    """Run the sweeps on `device`; writes accuracy.{md,csv,tex,json} and accuracy_pareto.png into
    out_dir and returns {"out_dir", "device", "rows": [...], "pareto": [...]}."""
    ensure_warp()
    device = str(device)
    if device == "auto":
        device = "cuda:0" if torch.cuda.is_available() else "cpu"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    threads = torch.get_num_threads()
    if not device.startswith("cuda"):
        torch.set_num_threads(1)  # Warp's CPU kernels are single-threaded; see fracture_gs.paper.figures
    try:
        t0 = time.perf_counter()
        warmup(device)
        spec = SWEEPS["quick" if quick else "full"]
        results = []
        for case in cases or spec:
            results += sweep(case, spec[case], device, progress)
        total = time.perf_counter() - t0
    finally:
        torch.set_num_threads(threads)
    cuda = device.startswith("cuda")
    name = (
        torch.cuda.get_device_name(torch.device(device))
        if cuda
        else f"CPU ({platform.processor() or platform.machine()}, Warp kernels single-threaded)"
    )
    command = "fracture-gs bench --accuracy" + (" --quick" if quick else "") + f" --device {device} --out {out_dir}"
    caption = (
        f"Error against wall time for Δx sweeps (fixed CFL) and Δt sweeps (fixed Δx) on cases with known answers: "
        f"bar = "
        f"relative error of the first longitudinal period against T = 2L/√(E/ρ) (ν = 0); spin = relative drift of "
        f"kinetic + elastic energy of a free spinning cube over {SPIN['T']} s; recontact = max interpenetration [m] of "
        f"two fragments under FractureFields' contact projection (exact answer 0). Device: {name}; "
        f"{datetime.date.today().isoformat()}; {'quick' if quick else 'full'} sweep, {total:.0f} s in all."
    )
    payload = {
        "device": device,
        "device_name": name,
        "date": datetime.date.today().isoformat(),
        "quick": quick,
        "command": command,
        "caption": caption,
        "total_s": total,
        "results": [r.__dict__ for r in results],
    }
    (out / "accuracy.json").write_text(json.dumps(payload, indent=2, default=float))
    write_outputs(payload, out)
    return {
        "out_dir": str(out),
        "device": device,
        "total_s": round(total, 1),
        "files": ["accuracy.md", "accuracy.csv", "accuracy.tex", "accuracy_pareto.png", "accuracy.json"],
    }


def write_outputs(payload: dict, out) -> None:
    """Table (MD/CSV/TEX) and Pareto PNG from an accuracy.json payload (the PNG is skipped where
    matplotlib is missing, e.g. on a bare GPU image: rerun `--from-json` elsewhere)."""
    out = Path(out)
    results = [Result(**r) for r in payload["results"]]
    accuracy_table(results, payload["caption"], payload["command"]).write(out)
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print("matplotlib is not installed: accuracy_pareto.png skipped (run --from-json where it is)")
        return
    pareto_figure(results, out / "accuracy_pareto.png", title=f"speed vs error on {payload['device_name']}")
