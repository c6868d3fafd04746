"""Typed configuration for every layer, as plain dataclasses (no torch, no warp).

These classes are the contract between the TOML files (`fracture_gs.io.config` loads them), the
simulator (`fracture_gs.sim` re-exports `SimConfig`), the renderer and the CLI. They live in a leaf
module so that `io` can build them without importing `sim` (docs/DESIGN.md: io imports neither sim nor
render). Units are SI throughout: metres, seconds, kilograms, pascals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal, Optional, get_args

from .variants import VariantName

Vec3 = tuple[float, float, float]

# the enum-like fields: each `Literal` is the one list of valid values (the TOML loader checks it)
MaterialName = Literal["fixed_corotated", "neo_hookean", "stvk_hencky_vm", "drucker_prager"]
PlaneMode = Literal["sticky", "slip", "friction"]
RegionKind = Literal["impulse", "velocity"]
GridKind = Literal["explicit", "auto"]
GridStorage = Literal["auto", "slots", "boxes"]
ParticleOrder = Literal["scene", "cell"]
ProviderName = Literal["none", "oracle", "stress", "voronoi"]
RenderMode = Literal["classic", "antialiased"]
RenderBackend = Literal["auto", "gsplat", "torch", "warp"]
ColorBy = Literal["appearance", "fragment"]
BandRelease = Literal["first", "all", "none"]
Preset = Literal["small", "paper"]
UpAxis = Literal["auto", "+x", "-x", "+y", "-y", "+z", "-z"]
RoiKind = Literal["auto", "box", "sphere", "all"]
LoadKind = Literal["auto", "pull", "drop", "impact", "shoot", "crush", "none"]
CameraSource = Literal["auto", "trainer", "config"]
CaptureQuality = Literal["draft", "default", "fine"]
CaptureMaterial = Literal["ceramic", "wood", "plant", "bread", "config"]
PanelSize = Literal["auto", "config"]
GroundKind = Literal["auto", "none"]
InteriorColor = Literal["surface", "material"]

MATERIALS = get_args(MaterialName)
PLANE_MODES = get_args(PlaneMode)
REGION_KINDS = get_args(RegionKind)
GRID_KINDS = get_args(GridKind)
PROVIDERS = get_args(ProviderName)
RENDER_MODES = get_args(RenderMode)
RENDER_BACKENDS = get_args(RenderBackend)
PRESETS: dict[str, float] = {"small": 1.0 / 64, "paper": 1.0 / 128}
"""Scene preset → the grid spacing Δx it selects: the size of a built-in scene and its grid."""
assert tuple(PRESETS) == get_args(Preset)
BUILTIN_SCENES = ("bread", "ficus", "recontact", "beam", "plane_drop", "plate_drop")


@dataclass
class PlaneBoundary:
    """Half-space collider {x : (x - point)·normal < 0} acting on grid nodes."""

    point: Vec3 = (0.0, 0.0, 0.0)
    """A point on the plane [m]."""
    normal: Vec3 = (0.0, 0.0, 1.0)
    """Outward normal, pointing into the free side [unitless, normalized on load]."""
    mode: PlaneMode = "slip"
    """`sticky` (v = 0), `slip` (only the approaching normal part removed) or `friction` (Coulomb)."""
    friction: float = 0.0
    """Coulomb coefficient μ for `friction` mode [unitless]."""


@dataclass
class CuboidBoundary:
    """Grid nodes inside an axis-aligned box get velocity `velocity`; the box moves with it.

    Used as grips (the bread is pulled apart at both ends) and moving pushers. With `push` set the box
    is a one-sided pusher instead (a press plate): it only removes the part of a node's velocity, relative
    to the box, that runs against `push`, so it drives material ahead of it without holding it."""

    lower: Vec3 = (0.0, 0.0, 0.0)
    """Box lower corner at `start` [m]."""
    upper: Vec3 = (0.0, 0.0, 0.0)
    """Box upper corner at `start` [m]."""
    velocity: Vec3 = (0.0, 0.0, 0.0)
    """Prescribed node velocity; the box translates with it [m/s]."""
    start: float = 0.0
    """Time the region switches on [s]."""
    end: float = 1e30
    """Time the region switches off [s]."""
    push: Vec3 = (0.0, 0.0, 0.0)
    """Direction the box pushes along, e.g. [0, 0, -1] for a plate pressing down [unitless, normalized];
    (0, 0, 0) = sticky: nodes inside take `velocity` whole (grips)."""


@dataclass
class SphereBoundary:
    """A kinematic rigid sphere (a projectile) moving at constant velocity, acting on grid nodes.

    At a node inside the sphere the part of the velocity that approaches the sphere's surface relative to
    the sphere is removed (v_rel = v − velocity, n the outward normal at the node; if v_rel·n < 0 then
    v ← v − (v_rel·n) n): it pushes material out of its way, never pulls or glues it."""

    center: Vec3 = (0.0, 0.0, 0.0)
    """Centre at `start` [m]."""
    radius: float = 0.0
    """Radius [m] (must be positive)."""
    velocity: Vec3 = (0.0, 0.0, 0.0)
    """Velocity; the sphere translates with it while active [m/s]."""
    start: float = 0.0
    """Time the sphere appears [s]."""
    end: float = 1e30
    """Time the sphere disappears [s]."""


@dataclass
class ParticleRegion:
    """A timed action on the particles inside an axis-aligned box (tested each substep).

    `kind = "impulse"`: the particles' velocity changes by `delta_v` in total, spread evenly over
    [start, end] (an impulse per unit mass). `kind = "velocity"`: their velocity is overridden
    with `velocity` during [start, end]."""

    kind: RegionKind = "impulse"
    """`impulse` or `velocity`."""
    lower: Vec3 = (0.0, 0.0, 0.0)
    """Box lower corner [m]."""
    upper: Vec3 = (0.0, 0.0, 0.0)
    """Box upper corner [m]."""
    delta_v: Vec3 = (0.0, 0.0, 0.0)
    """Total velocity change for `impulse` [m/s]."""
    velocity: Vec3 = (0.0, 0.0, 0.0)
    """Override velocity for `velocity` [m/s]."""
    start: float = 0.0
    """Start time [s]."""
    end: float = 0.0
    """End time [s]."""


@dataclass
class MaterialConfig:
    """Default constitutive parameters; `fracture_gs.sim.Particles` holds them per particle."""

    model: MaterialName = "fixed_corotated"
    """One of `fixed_corotated`, `neo_hookean`, `stvk_hencky_vm` (metal), `drucker_prager` (sand)."""
    E: float = 2.0e6
    """Young's modulus [Pa]."""
    nu: float = 0.3
    """Poisson ratio, in [0, 0.5)."""
    density: float = 200.0
    """Mass density ρ [kg/m³]; particle mass = ρ · volume."""
    yield_stress: float = 1.0e4
    """von Mises yield stress for `stvk_hencky_vm` [Pa]."""
    hardening: float = 0.0
    """Linear hardening: yield stress grows by `hardening` · 2μ · Δγ per return [unitless]."""
    friction_angle: float = 30.0
    """Drucker–Prager friction angle [degrees]."""
    sigma_R: float = 5.0e4
    """Fracture strength used by the stress event provider [Pa]."""


@dataclass
class MaterialMapEntry:
    """Parameters for the particles whose material label equals `label`; unset fields keep defaults."""

    label: int = 0
    """Material label (from the asset, or a PLY property named by `SceneConfig.material_property`)."""
    model: Optional[MaterialName] = None
    """Constitutive model for this label."""
    E: Optional[float] = None
    """Young's modulus [Pa]."""
    nu: Optional[float] = None
    """Poisson ratio."""
    density: Optional[float] = None
    """Density [kg/m³]."""
    yield_stress: Optional[float] = None
    """von Mises yield stress [Pa]."""
    hardening: Optional[float] = None
    """Hardening coefficient."""
    friction_angle: Optional[float] = None
    """Drucker–Prager friction angle [degrees]."""
    sigma_R: Optional[float] = None
    """Fracture strength [Pa]."""


ContactNormal = Literal["auto", "latched", "mass_gradient"]


@dataclass
class ContactConfig:
    """Contact between fragment fields at shared grid nodes (DESIGN.md "Many fragments")."""

    friction: float = 0.0
    """Coulomb coefficient μ between fragments [unitless]; 0 = the paper's frictionless projection."""
    normal: ContactNormal = "auto"
    """Contact normal and gate: `latched` (the first event's plane normal n_Π; fields touch where both
    carry interface-band mass: the paper), `mass_gradient` (per node n_ab ∝ ∇m_b − ∇m_a from the
    fields' nodal masses; fields touch where together they fill the node, see `fill`) or `auto`
    (latched for one plane cut into two fragments, mass gradient otherwise)."""
    fill: float = 0.5
    """Mass-gradient mode: two fields are in contact at a node where m_a + m_b ≥ fill · ρ̄Δx³ (ρ̄Δx³ a
    full node); 0.5 fires at gaps under ≈ 0.6 Δx (quadratic B-splines), 1 only on full overlap."""


@dataclass
class SimConfig:
    """MLS-MPM solver settings (DESIGN.md "Transfer equations", "Transfer variants")."""

    dt: float = 1e-4
    """Substep [s]; with `adaptive_dt` it is the upper bound."""
    adaptive_dt: bool = False
    """Choose Δt each frame from the CFL bound Δt ≤ cfl·Δx / (max|v| + wave speed)."""
    cfl: float = 0.4
    """CFL number for `adaptive_dt`."""
    gravity: Vec3 = (0.0, 0.0, -9.8)
    """Gravity vector [m/s²]."""
    variant: VariantName = "baseline"
    """Transfer variant: baseline, probe_latch, stress_zero, global_fragment_pass, local_multifield, full."""
    grid: GridKind = "explicit"
    """`explicit` (grid_origin, dx, grid_shape) or `auto` (fitted to the particles, see grid_margin)."""
    grid_origin: Vec3 = (0.0, 0.0, 0.0)
    """World position of node (0,0,0) [m]; rounded to a multiple of dx."""
    dx: float = 1.0 / 64
    """Grid spacing Δx [m]."""
    grid_shape: tuple[int, int, int] = (64, 64, 64)
    """Nodes per axis for an explicit grid."""
    grid_margin: float = 0.5
    """Auto grid: room left around the particles' bounds, as a fraction of their extent."""
    grid_bounds: Optional[tuple[Vec3, Vec3]] = None
    """Auto grid: world box (lower, upper) that must also be covered, e.g. to reach a floor [m]."""
    wall_cells: int = 3
    """Domain walls: nodes this close to the grid edge stop outward motion."""
    material: MaterialName = "fixed_corotated"
    """Default constitutive model (per-particle ids may override)."""
    boundaries: list = field(default_factory=list)
    """PlaneBoundary / CuboidBoundary / SphereBoundary / ParticleRegion instances."""
    restitution: float = 0.0
    """Contact projection restitution e in Eq. impulse (0 = perfectly inelastic normal)."""
    eps_mass: float = 1e-9
    """Field activity threshold ε_m as a fraction of the typical occupied-node mass ρ̄Δx³. Kept tiny
    so that fringe nodes still carry their particles' velocity (free fall stays exact)."""
    eps_band: float = 1e-6
    """Contact gate ε_band (band mass a field needs at a node), same unit as eps_mass."""
    max_substeps_per_frame: int = 100000
    """Safety bound on substeps in one frame (adaptive Δt)."""
    max_fragments: int = 64
    """Most fragment ids a run may create (K); providers stop splitting beyond it. Per-pair contact statistics
    (metrics.jsonl "pairs") cover the first 128 ids; contact between higher ids counts in the totals only."""
    field_slots: int = 4
    """Fields one grid node couples (S, 2…8). Slots: a node reached by more fragments merges the extra ones
    into its first field and counts a slot overflow. Boxes: the extra fields keep their own velocity (no
    contact with the others there) and are counted the same way."""
    grid_storage: GridStorage = "auto"
    """Where the fragment fields live after a latch (multi-field variants): `slots` (one dense grid plus a pool
    of extra slots at nodes two fragments reach), `boxes` (a dense box per fragment, fitted every frame;
    DESIGN.md "Grid storage: per-fragment boxes") or `auto` (the boxes, for one plane cut as for many pieces:
    the faster storage on a GPU, the same trajectories on the CPU)."""
    particle_order: ParticleOrder = "scene"
    """Order of the scene's Gaussians, and so of the particles: `scene` (as loaded) or `cell` (sorted once by grid
    cell before the run). In cell order a GPU's P2G sums each thread's run of particles that share a cell before
    its atomics (a P2G launch about a fifth shorter for the bread paper preset, less than half for Table 2's ficus;
    BENCHMARKS.md);
    choices drawn by particle index (Voronoi sites) then come out differently, and exported PLYs list the Gaussians
    in cell order."""
    contact: ContactConfig = field(default_factory=ContactConfig)
    """Fragment–fragment contact: friction and normals."""
    max_grid_cells: int = 16_777_216
    """Most grid nodes a run may allocate (256³ by default, ≈ 0.5 GiB of grid buffers); an automatic grid
    stretched by a far-away particle stops here with one sentence instead of exhausting memory."""


@dataclass
class OraclePlane:
    """One timed cut of the oracle provider: every fragment the plane crosses is split."""

    point: Vec3 = (0.0, 0.0, 0.0)
    """A point on the plane [m]."""
    normal: Vec3 = (1.0, 0.0, 0.0)
    """Plane normal; the new fragment of each cut lies on its positive side [unitless, normalized on load]."""
    latch_frame: int = 0
    """Frame at whose end the plane cuts (0 = before the first substep)."""
    latch_time: Optional[float] = None
    """Cut at the first frame end at or after this time [s] (overrides latch_frame)."""


@dataclass
class TopologyConfig:
    """Fracture event provider (DESIGN.md "Fracture event providers")."""

    provider: ProviderName = "none"
    """`none`, `oracle` (analytic planes), `stress` (stress-guided detection) or `voronoi` (pre-fracture
    into cells)."""
    point: Vec3 = (0.0, 0.0, 0.0)
    """Oracle plane point [m]."""
    normal: Vec3 = (1.0, 0.0, 0.0)
    """Oracle plane normal; fragment 1 lies on its positive side."""
    latch_frame: int = 0
    """Oracle: frame at whose end the plane latches (0 = before the first substep)."""
    latch_time: Optional[float] = None
    """Oracle: latch at the first frame end at or after this time [s] (overrides latch_frame)."""
    min_particles: int = 20
    """Stress: number of over-stressed particles needed."""
    persist_frames: int = 2
    """Stress: consecutive frames the condition must hold."""
    band_width: float = 1.0
    """Interface band half-width |distance| < band_width·Δx."""
    pair_radius: float = 1.5
    """Interface pairs: nearest opposite-band particle within pair_radius·Δx."""
    direction_agreement: float = 0.7
    """Stress: mean |cos| between principal directions below which the normal falls back to PCA."""
    planes: list = field(default_factory=list)
    """Oracle: OraclePlane list of timed cuts (`[[topology.planes]]`); empty = the single plane above."""
    max_events: int = 1
    """Stress: how many fracture events may latch (1 = the paper's single latch; more = repeated
    fracture, every over-stressed fragment cut again)."""
    release: BandRelease = "first"
    """Which bands get the stress release of the releasing variants: `first` (the first event's, the
    paper), `all` (every event's) or `none` (bands only mark crack faces: for shatters, where the bands
    of many cuts would cover most of the object and leave it stress-free)."""
    split_components: bool = True
    """After every event, give each disconnected piece of a fragment its own id."""
    min_fragment_particles: int = 8
    """Pieces with fewer particles stay with their parent fragment."""
    cells: int = 8
    """Voronoi: number of cells (seeded at particles)."""
    seed: int = 0
    """Voronoi: random seed of the cell sites."""
    impact_point: Optional[Vec3] = None
    """Voronoi: concentrate the cells around this point [m] (None = uniform over the object)."""
    impact_radius: float = 0.1
    """Voronoi: spread of the sites around impact_point (standard deviation) [m]."""
    latch_on_contact: bool = False
    """Voronoi: shatter at the first contact with a plane collider (instead of latch_frame / latch_time)."""


@dataclass
class CameraConfig:
    """A look-at camera, or an orbit around `target` when `orbit_degrees` ≠ 0 (OpenCV convention)."""

    eye: Vec3 = (0.5, -1.2, 0.6)
    """Camera position [m]."""
    target: Vec3 = (0.5, 0.5, 0.3)
    """Look-at point [m]."""
    up: Vec3 = (0.0, 0.0, 1.0)
    """World up vector."""
    fov_deg: float = 40.0
    """Vertical field of view [degrees]."""
    orbit_degrees: float = 0.0
    """Total azimuth swept around `up` over the run (0 = static camera)."""


@dataclass
class RenderConfig:
    """Rendering and video settings."""

    width: int = 256
    """Image width [px] (made even for H.264)."""
    height: int = 256
    """Image height [px]."""
    background: Vec3 = (1.0, 1.0, 1.0)
    """Background colour, RGB in [0, 1]."""
    fps: int = 24
    """Video frame rate."""
    mode: RenderMode = "classic"
    """gsplat rasterization mode: `classic` or `antialiased`."""
    backend: RenderBackend = "auto"
    """`auto` (gsplat on CUDA; on the CPU the Warp kernel, or torch where a gradient is needed), `gsplat` (CUDA),
    `torch` (the pure-torch tile rasterizer, any device, differentiable) or `warp` (CPU only, no gradient; its
    pixels are torch's within 1/255); DESIGN.md "Rendering"."""
    color_by: ColorBy = "appearance"
    """`appearance` (the Gaussians' own colours) or `fragment` (each fragment in its own colour, shaded by
    the Gaussian's brightness, once the object has broken)."""
    show_exposed_interior: bool = True
    """Draw interior fill particles once a fracture exposes them."""
    trim_cracks: bool = False
    """At each fracture event, shrink the drawn Gaussians that reach across the new surface to their own side,
    so the opening shows as it opens (`render/crack_faces.py`; on for captured scenes)."""
    max_stretch: Optional[float] = None
    """Largest principal stretch (and 1/it, compression) a drawn Gaussian takes from its particle's F [unitless,
    > 1]; None = F as it is. A brittle material breaks long before it stretches far, so stretch beyond its
    failure strain is unresolved fracture, drawn as needles; a captured object's preset sets 1 + 4 σ_R/E."""
    interior_color: InteriorColor = "surface"
    """Colour of exposed interior: `surface` (the nearest surface Gaussian's) or `material` (the material's
    own interior colour, `interior_rgb`)."""
    interior_rgb: Vec3 = (0.85, 0.82, 0.76)
    """Interior colour for interior_color = "material", RGB in [0, 1] (a capture's material preset sets it)."""
    inset_radius: int = 40
    """Radius of the circular fracture inset [px]."""
    inset_zoom: float = 2.5
    """Magnification of the inset."""
    camera: CameraConfig = field(default_factory=CameraConfig)
    """Camera rig."""


@dataclass
class MaterialRegion:
    """A box of a captured scene made of another material preset (`[[capture.regions]]`): its Gaussians get
    label REGION_LABEL + its index and a `material_map` entry with the preset's constants."""

    lower: Vec3 = (0.0, 0.0, 0.0)
    """Box lower corner [scene units, the file's own coordinates]."""
    upper: Vec3 = (0.0, 0.0, 0.0)
    """Box upper corner [scene units]."""
    material: CaptureMaterial = "wood"
    """Preset of the Gaussians inside (`ceramic`, `wood`, `plant` or `bread`)."""


REGION_LABEL = 1000
"""Material label of `capture.regions[0]` (the next region's is one more)."""


@dataclass
class CaptureConfig:
    """How a captured 3DGS PLY (any trainer's output, in its own units and axes) becomes a simulated
    object: clean-up, region of interest, a uniform fit into the grid, interior fill, a load that breaks
    it and a camera that frames it. Positions below are in the scene's own coordinates; `auto` values
    are resolved when the scene is loaded (`fracture-gs init scene.ply` writes them out)."""

    fit: bool = True
    """Fit the PLY into the simulation domain (false: use its coordinates as metres, as written)."""
    up: UpAxis = "auto"
    """The scene's up axis (`auto`: from the trainer's cameras.json beside the PLY, else `-y`, COLMAP's)."""
    min_opacity: float = 0.01
    """Floaters: Gaussians fainter than this are dropped."""
    outlier_neighbours: int = 8
    """Statistical outlier removal: neighbours averaged (0 = off)."""
    outlier_std: float = 3.0
    """A Gaussian whose mean distance to its neighbours exceeds mean + outlier_std·std is dropped."""
    ground: GroundKind = "auto"
    """The ground the object stands on (pavement, a table top): `auto` finds a flat layer at the bottom that
    spans the scene and keeps it as a static background (`capture/ground.py`); `none` keeps every Gaussian a
    candidate for the object."""
    ground_level: Optional[float] = None
    """Height of the ground's top along the up axis [scene units], below which Gaussians are background (None =
    found by `ground = "auto"`, or no ground)."""
    roi: RoiKind = "auto"
    """Region simulated: `auto` (robust bounds of what is left), `box`, `sphere` or `all`; the rest is a
    static background, rendered but not simulated."""
    roi_lower: Optional[Vec3] = None
    """Box ROI lower corner [scene units]."""
    roi_upper: Optional[Vec3] = None
    """Box ROI upper corner [scene units]."""
    roi_center: Optional[Vec3] = None
    """Sphere ROI centre [scene units]."""
    roi_radius: Optional[float] = None
    """Sphere ROI radius [scene units]."""
    percentile: float = 1.0
    """Auto ROI: per-axis bounds at this percentile and its complement (robust to stray Gaussians) [%]."""
    size: float = 0.5
    """Length of the object's longest side after the fit [m] (materials and loads are tuned at this scale)."""
    cells_across: Optional[int] = None
    """Grid cells across the object's longest side: Δx = size / cells_across (None = automatic: from the
    thickness of the object's thinnest parts, within `quality`'s budget for the device)."""
    quality: CaptureQuality = "default"
    """Resolution budget for the automatic Δx: `draft`, `default` or `fine` (cells across and simulated
    particles per device; the CPU's `default` keeps a 40-frame, three-variant run of a 150k-Gaussian capture
    within a few minutes)."""
    material: CaptureMaterial = "ceramic"
    """Material preset of the object: `ceramic` (stiff, brittle: shards), `wood`, `plant` (bends, then snaps),
    `bread` (soft, tears) or `config` ([material] as written). Stiffness is the stiffest each time step
    affords (see `capture/materials.py`); Δt follows from its CFL bound."""
    regions: list = field(default_factory=list)
    """MaterialRegion list (`[[capture.regions]]`): boxes of the scene made of another preset (a pot of
    ceramic under a plant); a PLY label property with `material_property` and `[[material_map]]` does the same
    per Gaussian."""
    panel: PanelSize = "auto"
    """Video panel size: `auto` (640×480 on the CPU, 1280×720 on a GPU) or `config` ([render] width and
    height as written; `--resolution` sets them)."""
    max_particles: Optional[int] = None
    """Budget of interior fill particles (the fill spacing grows to respect it); None = the particle budget of
    `quality` on the device."""
    fill_threshold: float = 0.2
    """Fill: opacity-weighted density of an occupied voxel."""
    fill_closing: int = 1
    """Fill: holes narrower than about 2·fill_closing voxels are closed before the flood fill."""
    seal_bottom: bool = True
    """Fill: close the object's underside with a virtual floor at its lowest layer before the flood fill (an
    object captured standing on the ground has no bottom surface; false: only what its Gaussians close)."""
    load: LoadKind = "auto"
    """What breaks the object: `auto` (a `drop`: a fall breaks any shape without grips to place), `pull` (grips
    at both ends of its longest axis), `drop` (falls onto a floor), `impact` (a velocity kick at a point on its
    side), `shoot` (a rigid ball flies into its side), `crush` (a plate presses it onto the floor) or `none`.
    Added only to a config without [[sim.boundaries]] of its own (those are the load then)."""
    load_speed: float = 0.0
    """Grip speed [m/s] (pull), impact speed (impact), initial downward speed (drop), ball speed (shoot) or
    plate speed (crush); 0 = automatic."""
    camera: CameraSource = "auto"
    """`auto` (frames the object), `trainer` (a view of the trainer's cameras.json) or `config`
    ([render.camera] as written)."""
    cameras_json: Optional[str] = None
    """Path of the trainer's cameras.json (None: looked for beside the PLY and up to three folders up)."""
    view: int = 0
    """Index of the trainer view when camera = "trainer"."""
    scale: Optional[float] = None
    """Resolved fit: metres per scene unit (None = automatic)."""
    rotation: Optional[tuple[Vec3, Vec3, Vec3]] = None
    """Resolved fit: 3×3 rotation, scene axes → simulation axes (None = from `up` and the object's axes)."""
    offset: Optional[Vec3] = None
    """Resolved fit: x_sim = scale · rotation · x_scene + offset [m] (None = automatic)."""


@dataclass
class SceneConfig:
    """Everything a run needs: what to load, how to simulate it, how to break it and draw it."""

    name: str = "scene"
    """Run name (used for output folders)."""
    scene: str = "bread"
    """Built-in asset name (bread, ficus, recontact, beam, plane_drop) or a path to a captured scene: a 3DGS or
    compressed .ply, a .splat or a .spz (the format is read from the content)."""
    preset: Preset = "small"
    """Built-in asset size: `small` (≈20k particles, CPU) or `paper` (the paper's counts)."""
    particles: Optional[int] = None
    """Override a built-in scene's particle count (quick looks and tests); None = the preset's."""
    fill_interior: bool = True
    """Fill the inside of a surface-only PLY with simulated particles."""
    material_property: Optional[str] = None
    """PLY property holding an integer material label for `material_map`."""
    frames: int = 30
    """Number of frames to simulate."""
    frame_dt: float = 0.01
    """Time between frames [s]."""
    initial_velocity: Vec3 = (0.0, 0.0, 0.0)
    """Velocity given to every particle at t = 0 [m/s]."""
    sim: SimConfig = field(default_factory=SimConfig)
    """Solver settings."""
    material: MaterialConfig = field(default_factory=MaterialConfig)
    """Default material."""
    material_map: list = field(default_factory=list)
    """MaterialMapEntry list: per-label overrides for heterogeneous objects."""
    topology: TopologyConfig = field(default_factory=TopologyConfig)
    """Fracture event provider."""
    render: RenderConfig = field(default_factory=RenderConfig)
    """Rendering."""
    capture: CaptureConfig = field(default_factory=CaptureConfig)
    """How a captured PLY scene is cleaned, fitted, filled, loaded and framed (ignored for built-in scenes)."""
    variants: list = field(default_factory=lambda: ["baseline", "stress_zero", "full"])
    """Variants `render-sim` runs side by side by default."""


BOUNDARY_TYPES: dict[str, type] = {
    "plane": PlaneBoundary,
    "cuboid": CuboidBoundary,
    "sphere": SphereBoundary,
    "region": ParticleRegion,
}
"""Value of a `[[sim.boundaries]]` table's `type` key → boundary class."""
