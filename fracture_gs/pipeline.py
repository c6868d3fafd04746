"""Scene → simulator → per-frame Gaussians: the path shared by the render-sim job and `FractureSim`.

Frame 0 is the initial state; frame f ≥ 1 is the state after f·frame_dt. Each frame yields the
Gaussians' means x_p, covariances Σ_p = F_p Σ_p⁰ F_pᵀ, the polar rotations R(F_p) (for SH) and
the fragment ids, as tensors on the simulation device (no host copies).
"""

from __future__ import annotations

import copy
import functools
from typing import TYPE_CHECKING, Iterator, Optional, Union, cast

import torch

from . import assets
from .config import SceneConfig
from .errors import ArgumentError
from .io import GaussianSet
from .io.gaussian_set import Carrier
from .profiling import phases
from .render.gaussians import deform_covariances, limit_stretch, polar_rotation
from .sim import Particles, SimulationError, Simulator, Topology
from .sim.grid.domain import fit_grid
from .sim.neighbourhood import cell_order
from .sim.providers import ReplayProvider, make_provider
from .variants import VariantName

if TYPE_CHECKING:
    from .render.crack_faces import CrackFaces


class FrameOutput:
    """One frame of one run: particle means, fragment ids and metrics, read off the simulator; the
    covariances Σ = F Σ⁰ Fᵀ and the polar rotations R(F) (for SH) are computed when first asked for,
    so a renderer on another thread pays for them there."""

    def __init__(
        self,
        frame: int,
        time: float,
        means: torch.Tensor,
        F: torch.Tensor,
        cov0: torch.Tensor,
        fragment: torch.Tensor,
        band: torch.Tensor,
        metrics: Optional[dict] = None,
        substeps: int = 0,
        topology_version: int = -1,
    ):
        self.frame, self.time, self.substeps = frame, time, substeps
        # fracture events so far (−1: unknown): fragment and band change only with it
        self.topology_version = topology_version
        self.means = means  # [N, 3]
        self.F = F  # [N, 3, 3]
        self.cov0 = cov0  # [N, 3, 3] rest covariances
        self.fragment = fragment  # [N] int32, −1 before the latch
        self.band = band  # [N] int32
        self.metrics = metrics if metrics is not None else {}
        self.ready: Optional[torch.cuda.Event] = None  # after the copies above, for a consumer on another stream
        self.max_stretch: Optional[float] = None  # drawn covariances take at most this principal stretch of F
        self.rotation64: Optional[torch.Tensor] = None  # [N, 3, 3] R(F) in float64 from the diagnostics, or None

    @functools.cached_property
    def covars(self) -> torch.Tensor:  # [N, 3, 3]
        F = self.F if self.max_stretch is None else limit_stretch(self.F, self.max_stretch)
        return deform_covariances(F, self.cov0)

    @functools.cached_property
    def rotations(self) -> torch.Tensor:  # [N, 3, 3] R(F)
        """R(F) in F's dtype: the diagnostics' float64 R of this F when they computed it (`rotation64`; float32
        `polar_rotation` converts each F to float64 and rounds its R once, so these are the same bits), else
        computed now."""
        if self.rotation64 is not None:
            return self.rotation64.to(self.F.dtype)
        return polar_rotation(self.F)


def check_config(cfg: SceneConfig, source: str) -> None:
    """A config built or edited in Python, checked as the loader checks a file: types and shapes (a gravity of
    two numbers, a frame count given as text) and then every value, through the same code (`config_from_dict`
    of its plain form). Raises ConfigError naming `source` and the key."""
    from .io.config import config_from_dict
    from .io.config.dump import config_to_dict

    if not isinstance(cfg, SceneConfig):
        raise ArgumentError(
            f"{source}: cfg must be a SceneConfig, got {type(cfg).__name__}; load one with load_config."
        )
    config_from_dict(config_to_dict(cfg), source)


def prepare_scene(cfg: SceneConfig, device="cpu"):
    """The config's scene, ready to simulate: a `capture.scene.Capture` holding the (resolved) config,
    the simulated Gaussians on `device`, the static background and the capture fit. A built-in asset
    comes at the config's preset; a PLY goes through `capture.resolve` (clean-up, fit, fill, load,
    camera) and its material labels are read from `material_property`."""
    from .capture.scene import Capture, resolve
    from .io.ply import as_device

    device = str(as_device("prepare_scene", device))
    if not isinstance(cfg, SceneConfig):
        raise ArgumentError(
            f"prepare_scene: cfg must be a SceneConfig, got {type(cfg).__name__}; load one first, e.g. "
            "prepare_scene(fracture_gs.io.load_config('bread'))."
        )
    if cfg.scene in assets.names():
        check_config(cfg, f"prepare_scene: {cfg.name}")  # a config built or edited in Python (resolve checks a PLY's)
        gs = assets.build(cfg.scene, size=cfg.preset, n=cfg.particles).to(device)
        return Capture(cfg, in_particle_order(gs, cfg), None, None, [])
    cap = resolve(cfg, device)
    gs = cap.gaussians
    if cfg.material_property:
        if cfg.material_property not in gs.extra:
            raise SimulationError(
                f"{cfg.scene}: material_property '{cfg.material_property}' is not a vertex property of the scene "
                f"(its extra properties: {', '.join(sorted(gs.extra)) or 'none'}); name one of them or remove "
                "material_property."
            )
        gs.labels = gs.extra[cfg.material_property].to(torch.int32)
        if gs.carrier is not None:  # the simulated particles carry the labels that set their material
            p = gs.carrier.particles
            p.labels = p.extra[cfg.material_property].to(torch.int32)
    cap.gaussians = in_particle_order(gs.to(device), cfg)
    return cap


def in_particle_order(gs: GaussianSet, cfg: SceneConfig) -> GaussianSet:
    """The Gaussians in the order `sim.particle_order` asks for: as loaded (`scene`), or sorted by the cell of
    their stencil's base node on the run's grid (`cell`, `neighbourhood.cell_order`), so that consecutive
    particles share their 27 nodes and a GPU's P2G sums them before its atomics. Every variant of a run starts
    from these Gaussians, so they share one particle order (the topology's labels are per particle)."""
    if cfg.sim.particle_order != "cell" or len(gs) == 0:
        return gs
    if gs.carrier is not None:  # the simulated particles are sorted; the drawn Gaussians keep their order
        means = gs.carrier.particles.means.detach().float()
        origin, dx, shape = fit_grid(cfg.sim, means)
        return gs.replace(carrier=gs.carrier.reordered(cell_order(means, origin, dx, shape, "cell")))
    means = gs.means.detach().float()
    origin, dx, shape = fit_grid(cfg.sim, means)
    return gs.subset(cell_order(means, origin, dx, shape, "cell"))


def load_scene(cfg: SceneConfig, device="cpu") -> GaussianSet:
    """The simulated Gaussians of `prepare_scene` (a PLY's config should be the resolved one a run wrote,
    so that the grid and loads match the fit)."""
    return prepare_scene(cfg, device).gaussians


def check_inside_grid(sim: Simulator, source: str) -> None:
    """A scene that does not fit the grid is a config error, not a silent clamp."""
    g = sim.grid
    lo = torch.tensor(g.origin, device=sim.particles.x.device) + (sim.cfg.wall_cells - 1) * g.dx
    hi = (
        torch.tensor(g.origin, device=sim.particles.x.device)
        + (torch.tensor(g.shape, device=lo.device) - sim.cfg.wall_cells) * g.dx
    )
    x = sim.particles.x
    outside = int(((x < lo) | (x > hi)).any(dim=1).sum())
    if outside:
        raise SimulationError(
            f"{source}: {outside} of {len(x)} particles lie outside the simulation grid "
            f'[{lo.tolist()}, {hi.tolist()}]; enlarge sim.grid_shape, move sim.grid_origin or use sim.grid = "auto"'
        )


def make_simulator(
    cfg: SceneConfig,
    gs: GaussianSet,
    variant: str,
    device: str,
    topology: Union[Topology, list, None] = None,
    provider=None,
) -> Simulator:
    """A simulator for one variant. `topology` (a saved one, or a run's history of them) is replayed at its
    latch frame instead of running the event provider, so every variant uses the same topology; `baseline` runs no
    provider but still receives the saved labels for its diagnostics (its transfer ignores them). `provider`, if
    given, replaces both (variants running side by side on several devices share one live topology)."""
    sim_cfg = copy.deepcopy(cfg.sim)
    sim_cfg.variant = cast(VariantName, variant)  # checked by the Simulator
    simulated = gs.carrier.particles if gs.carrier is not None else gs  # a carried set simulates its particles
    particles = Particles.from_gaussians(simulated, cfg, dx=sim_cfg.dx)
    if provider is None and topology is not None:
        provider = ReplayProvider(topology)
    elif provider is None and variant != "baseline":
        provider = make_provider(cfg.topology)
    sim = Simulator(sim_cfg, particles, device=device, provider=provider)
    check_inside_grid(sim, cfg.name)
    return sim


def frame_output(
    sim: Simulator, cov0: torch.Tensor, metrics: dict, substeps: int = 0, carrier: Optional[Carrier] = None
) -> FrameOutput:
    """The simulator's state as a frame of the drawn Gaussians (through `carrier` when they are carried)."""
    P = sim.particles
    if carrier is not None:
        means, F = carrier.carry(P.x, P.F)
        fragment, band = P.fragment.index_select(0, carrier.index), P.band.index_select(0, carrier.index)
    else:
        means, F, fragment, band = P.x.clone(), P.F.clone(), P.fragment.clone(), P.band.clone()
    return FrameOutput(
        frame=sim.frame,
        time=sim.time,
        means=means,
        F=F,
        cov0=cov0,
        fragment=fragment,
        band=band,
        metrics=metrics,
        substeps=substeps,
        topology_version=len(sim.topologies),
    )


def simulate(
    sim: Simulator,
    cov0: torch.Tensor,
    frames: int,
    frame_dt: float,
    diagnostics: bool = True,
    carrier: Optional[Carrier] = None,
    crack_faces: bool = False,
    max_stretch: Optional[float] = None,
) -> Iterator[FrameOutput]:
    """Yield frame 0 (initial state), then one FrameOutput per simulated frame. Raises
    `SimulationDiverged` at the frame that diverged (everything yielded before stays valid).
    Without `diagnostics` nothing is read back to the host but the per-frame divergence check. With a
    `carrier` the frames hold the carried Gaussians (cov0 is theirs), the metrics the simulated particles.
    With `crack_faces` the frames' rest covariances are trimmed at each fracture event's surfaces
    (`render.crack_faces.CrackFaces`); with `max_stretch` their drawn covariances take at most that principal
    stretch (or 1/it compression) of F (`render.gaussians.limit_stretch`)."""
    tracker = sim.diagnostics_tracker() if diagnostics else None
    with phases.section("diagnostics"):
        first = tracker.snapshot() if tracker else {}
    out = frame_output(sim, cov0, first, carrier=carrier)
    if tracker is not None and carrier is None:  # carried Gaussians rotate by their own F
        out.rotation64 = tracker.take_rotation()
    trim = _CrackTrim(out, sim, cov0, carrier) if crack_faces else None
    out.max_stretch = max_stretch
    yield out
    for _ in range(frames):
        with phases.section("simulate"):
            n = sim.advance(frame_dt)
            out = frame_output(sim, cov0, tracker.history[-1] if tracker else {}, n, carrier)
            if tracker is not None and carrier is None:
                out.rotation64 = tracker.take_rotation()
            if trim is not None:
                out.cov0 = trim(out, sim)
            out.max_stretch = max_stretch
        yield out


class _CrackTrim:
    """The trimmed rest covariances of a run, recomputed when its topology changes."""

    def __init__(self, first: FrameOutput, sim: Simulator, cov0: torch.Tensor, carrier: Optional[Carrier]):
        self.means0, self.x0 = first.means.clone(), sim.particles.x.clone()
        self.cov0, self.carrier = cov0, carrier
        self.faces: Optional[CrackFaces] = None
        self.version, self.current = 0, cov0

    def __call__(self, out: FrameOutput, sim: Simulator) -> torch.Tensor:
        if out.topology_version != self.version and bool((out.fragment >= 0).any()):
            from .render.crack_faces import CrackFaces

            if self.faces is None:
                index = self.carrier.index if self.carrier is not None else None
                self.faces = CrackFaces(self.means0, self.cov0, self.x0, index)
            self.current = self.faces.trimmed(sim.particles.fragment)
            self.version = out.topology_version
        return self.current
