"""Configuration: frozen dataclasses, one per component, and the named presets.

`paper` holds the paper's settings (Sec. 3, ../shared/paper); `fast` is sized for a 2-core CPU. A
JSON/TOML file may override any field by its nested name. Each section checks its values when it
is built (type, mode, range), so a wrong value is a one-line error naming its key before a run
starts. Why a default is what it is: docs/decisions.md.
"""
from __future__ import annotations

import dataclasses
import json
import math
import tomllib
import types
from dataclasses import dataclass, field, fields, is_dataclass, replace
from functools import cache
from pathlib import Path
from typing import Any, ClassVar, Literal, Union, get_args, get_origin, get_type_hints

from nicer_stream.errors import UserError
from nicer_stream.losses.weights import LossWeights


# Ranges beyond "a number >= 0", which every int and float setting must be.
FRACTIONS = {"fine_start", "ba_start", "final_color_start", "batch_color_start", "keyframe_min_overlap",
             "evidence_ratio", "fill_min_inliers", "min_ncc", "final_lr_end_factor"}
POSITIVE = {"max_side", "fusion_max_side", "rays", "chunk_rays", "resolution", "beta_voxels", "lr", "half_extent",
            "coarse_res", "fine_res_min", "fine_res_max", "color_res_min", "color_res_max", "window", "corners"}
SIGNED = {"centre"}


def _accepts(hint: Any, value: Any, name: str) -> str | None:
    """None when `value` fits the annotation `hint` and the range of `name`, else what it must be."""
    if get_origin(hint) in (Union, types.UnionType):
        args = [a for a in get_args(hint) if a is not type(None)]
        if value is None:
            return None if len(args) < len(get_args(hint)) else "must be set"
        hint = args[0]
    if get_origin(hint) is Literal:
        return None if value in get_args(hint) else "must be one of " + ", ".join(repr(a) for a in get_args(hint))
    if get_origin(hint) is tuple:
        ok = isinstance(value, tuple) and len(value) == len(get_args(hint))
        ok = ok and all(_accepts(a, v, name) is None for a, v in zip(get_args(hint), value))
        return None if ok else f"must be {len(get_args(hint))} numbers"
    if hint is bool:
        return None if isinstance(value, bool) else "must be true or false"
    if hint is str:
        return None if isinstance(value, str) else "must be a string"
    if hint in (int, float):
        kind = "an integer" if hint is int else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float) if hint is float else int):
            return f"must be {kind}"
        if name in SIGNED:
            return None if math.isfinite(value) else f"must be {kind}"
        if name in FRACTIONS:
            return None if 0 <= value <= 1 else f"must be {kind} in [0, 1]"
        if name in POSITIVE:
            return None if 0 < value < math.inf else f"must be {kind} > 0"
        return None if 0 <= value < math.inf else f"must be {kind} >= 0"
    return None


@cache
def _hints(cls: type) -> dict[str, Any]:
    return get_type_hints(cls)


def check(section: Any, where: str) -> None:
    """Raise a one-line UserError naming the first field of `section` whose value does not fit."""
    for f in fields(section):
        value = getattr(section, f.name)
        if is_dataclass(value):
            continue
        problem = _accepts(_hints(type(section))[f.name], value, f.name)
        if problem:
            raise UserError(f"{where}{f.name} {problem}, got {value!r}")


class Checked:
    """A config section that checks its values when built (a preset, `replace`, a file)."""

    where: ClassVar[str] = ""

    def __post_init__(self) -> None:
        check(self, self.where)


@dataclass(frozen=True)
class ModelConfig(Checked):
    """Hierarchical scene representation (Sec. 3.1)."""

    where: ClassVar[str] = "model."

    pe_levels: int = 6
    """Positional-encoding frequencies of x for the geometry MLPs."""
    coarse_res: int = 32
    """Coarse dense grid resolution (vertices per axis)."""
    coarse_dim: int = 32
    """Coarse grid feature width."""
    coarse_hidden: int = 64
    """Coarse MLP hidden width (one hidden layer)."""
    fine_levels: int = 8
    """Number of fine dense grids."""
    fine_dim: int = 4
    """Feature width per fine level."""
    fine_res_min: int = 32
    """Coarsest fine resolution (Eq. 2)."""
    fine_res_max: int = 128
    """Finest fine resolution (Eq. 2)."""
    fine_hidden: int = 64
    """Fine MLP hidden width."""
    fine_layers: int = 3
    """Fine MLP hidden layers."""
    geo_feature_dim: int = 32
    """Geometric feature width output by each geometry MLP (z_coarse, z_fine)."""
    color_levels: int = 16
    """Colour hash-grid levels."""
    color_dim: int = 2
    """Colour feature width per level."""
    color_res_min: int = 16
    """Coarsest colour resolution."""
    color_res_max: int = 2048
    """Finest colour resolution."""
    color_log2_table: int = 22
    """log2 of hash-table rows per level (the release uses 24: ~6 GB with Adam state)."""
    color_hidden: int = 64
    """Colour MLP hidden width."""
    color_layers: int = 2
    """Colour MLP hidden layers."""
    view_pe_levels: int = 4
    """Positional-encoding frequencies of the view direction."""
    sphere_radius: float = 0.9
    """Geometric initialisation: SDF = radius - |x| (camera inside a sphere), in normalised units."""
    sphere_centre: Literal["bound", "camera", "auto"] = "auto"
    """SLAM's initial sphere: 'bound' (the bound's centre, `sphere_radius`), 'camera' (the first camera,
    radius its median depth) or 'auto' ('camera' when the camera lies outside the bound's sphere)."""


@dataclass(frozen=True)
class RenderConfig(Checked):
    """Ray sampling and volume rendering (Sec. 3.2)."""

    where: ClassVar[str] = "render."

    n_probe: int = 640
    """Uniform samples per ray evaluated without gradient to place the others."""
    n_importance: int = 64
    """Importance samples per ray (with gradient)."""
    n_uniform: int = 32
    """Extra stratified samples per ray (with gradient)."""
    probe_stop_tau: float | None = 16.0
    """A ray's probes stop once its optical depth passes this (the skipped weights sum to less than
    e^-tau); None evaluates every probe. The same samples, computed faster."""
    min_transmittance: float = 0.0
    """With gradient, samples whose estimated transmittance is below this skip the network
    (`render/live_samples.py`); 0: every sample. Mapping keeps 0 (docs/decisions.md)."""
    keep_band_m: float = 0.0
    """With `min_transmittance`: samples within this distance behind a surface go through the network
    anyway (the Eikonal term's points); 0: none. An option (docs/decisions.md)."""
    near_m: float = 0.05
    """Closest sample distance from the camera, metres."""
    beta_mode: Literal["adaptive", "global", "fixed"] = "adaptive"
    """'adaptive' (Eq. 8, voxel counts), 'global' (one learnable beta, VolSDF) or 'fixed'."""
    beta_fixed: float = 0.01
    """Beta for 'fixed' mode and the initial value for 'global' (normalised units)."""
    beta_c0: float = 1.208e-2
    """Eq. 8 constant c0."""
    beta_c1: float = 6.26471e-6
    """Eq. 8 constant c1 (per counted sample)."""
    beta_c2: float = 2.3e-3
    """Eq. 8 constant c2."""
    beta_voxels: int = 64
    """Voxel counter resolution per axis."""
    beta_count_weight: float = 1.0
    """Each mapping sample adds this to its voxel's count; fewer rays than the paper's with a weight
    of paper/ours keep its count-per-effort curve."""
    chunk_rays: int = 2048
    """Rays per chunk when rendering whole images without gradient."""


@dataclass(frozen=True)
class LossConfig(Checked):
    """Mapping losses (Sec. 3.3)."""

    where: ClassVar[str] = "loss."

    def __post_init__(self) -> None:
        check(self, self.where)
        check(self.weights, "loss.weights.")

    weights: LossWeights = field(default_factory=LossWeights)
    """Term weights (Eq. 12)."""
    warp_frames: int = 2
    """Other window frames each ray is warped into (warping and flow terms)."""
    metric_prior_alignment: bool = True
    """`map` (known poses): supervise depth with each frame's metric (w, q) from flow
    triangulation; False refits (w, q) by least squares every iteration (Eq. 10)."""
    slam_prior_alignment: Literal["lstsq", "map", "flow"] = "lstsq"
    """SLAM's depth-prior (w, q): 'lstsq' refit every iteration (Eq. 10), 'map' fitted once to the
    map's render when first mapped, 'flow' by flow triangulation at every mapping call."""
    first_depth_median_m: float = 2.0
    """First SLAM mapping: the first frame's depth-prior median is taken as this many metres, its
    shift from the normal prior (`mapping/depth_shift.py`; the paper fixes w=20, q=0)."""
    affine_brightness: bool = False
    """Optimise each mapped frame's affine brightness (gain exp(a), bias b) with the map, correcting
    the RGB and warping terms; the first frame holds (0, 0). Not in the paper."""
    huber_delta: float = 0.0
    """RGB and warping residuals: Huber-smoothed L1 with this threshold per channel
    (`losses/robust.py`), for blur and rolling shutter; 0: the paper's L1."""


@dataclass(frozen=True)
class MappingConfig(Checked):
    """Mapping optimiser and schedule (Sec. 3.3-3.4)."""

    where: ClassVar[str] = "mapping."

    iters: int = 100
    """Iterations per mapping call."""
    final_iters: int | None = None
    """Iterations of a closing mapping call in `finish()` over the last window with the poses fixed;
    None: the paper's schedule (the last frame mapped with `iters` unless just mapped)."""
    first_iters: int = 100
    """Iterations of the first mapping call (initialisation from the sphere)."""
    final_color_start: float | None = None
    """The closing call: fraction of its iterations after which the colour grids join; None: at
    `ba_start`."""
    final_lr_end_factor: float = 1.0
    """The `final_iters` call: the scene's learning rates at its end as a fraction of their
    start (a cosine over its iterations); 1: constant, as in every other call."""
    rays: int = 8096
    """Rays per iteration, spread over the window's frames."""
    fine_start: float = 0.25
    """Fraction of iterations after which the fine SDF joins."""
    ba_start: float = 0.75
    """Fraction after which colour grids and window poses join (local BA)."""
    lr: float = 2e-3
    """Base learning rate (MLPs)."""
    lr_geo_grid_factor: float = 20.0
    """Coarse and fine grid learning-rate factor."""
    lr_color_grid_factor: float = 5.0
    """Colour grid learning-rate factor."""
    lr_pose: float = 1e-3
    """Learning rate of window poses during local BA."""
    lr_brightness: float = 1e-2
    """Learning rate of the frames' affine brightness (a, b) (with `loss.affine_brightness`)."""
    every: int = 5
    """Map every this many frames."""
    keyframe_every: int = 10
    """Add a keyframe every this many frames (`keyframes = "stride"`)."""
    keyframes: Literal["stride", "view"] = "stride"
    """'stride': a keyframe every `keyframe_every` frames, a mapping call every `every`; 'view': a
    keyframe when the view changed (the thresholds below) and a mapping call at each."""
    keyframe_min_overlap: float = 0.6
    """'view': a keyframe once fewer than this share of the last keyframe's tracks are still seen."""
    keyframe_max_baseline: float = 0.1
    """'view': ... or the camera moved this fraction of the scene's median depth from it."""
    keyframe_max_rotation_deg: float = 15.0
    """'view': ... or turned this many degrees from it."""
    keyframe_max_gap_s: float = 1.0
    """'view': ... or this many seconds passed (a camera that keeps changing slowly)."""
    full_res_keyframes: int = 64
    """Keyframes kept at full resolution (the newest, and the first); older ones are halved without
    their flows (~1/6 of the memory). 0: all at full resolution."""
    window_random: int = 5
    """Window frames drawn at random from all keyframes."""
    window_recent: int = 10
    """Window frames drawn from the latest `recent_pool` keyframes."""
    recent_pool: int = 20
    """Size of the recent-keyframe pool."""
    eikonal_points: int = 1024
    """Extra uniformly sampled points for the Eikonal term per iteration."""
    batched_terms: bool = True
    """Compute all window frames' loss terms at once (`batched_objective.py`); False: frame by frame
    (`objective.py`, the reference). The same terms either way."""
    init: Literal["first_frame", "two_view", "auto"] = "first_frame"
    """How the first mapping fixes scale and shift: 'first_frame' (the shift from the normal prior),
    'two_view' (two posed views, docs/usage.md) or 'auto' ('first_frame' with a depth prior)."""
    init_frames: int = 10
    """'two_view' with a depth prior: frames after the first that the second view waits for."""
    init_max_frames: int = 60
    """'two_view' without a depth prior: frames held at most while the frontend's tracks reach
    `frontend.init_parallax_deg`; then the first frame starts alone (docs/decisions.md)."""
    batch_iters: int = 2000
    """Iterations of `nicer-stream map` (all frames in one window, known poses)."""
    batch_color_start: float = 0.25
    """`map` and the first SLAM mapping: fraction of iterations after which the colour grids join
    (docs/decisions.md)."""


@dataclass(frozen=True)
class TrackingConfig(Checked):
    """Camera tracking (Sec. 3.3)."""

    where: ClassVar[str] = "tracking."

    iters: int = 100
    """Iterations per frame."""
    rays: int = 1024
    """Pixels sampled afresh each iteration."""
    lr: float = 5e-3
    """Adam learning rate on the pose twist."""
    init: Literal["previous", "constant_velocity", "flow"] = "constant_velocity"
    """'previous', 'constant_velocity', or 'flow': PnP on the flow prior from the stored
    keyframes with the depth the map renders there (falls back to the previous pose)."""
    flow_points: int = 2000
    """Flow correspondences drawn per keyframe for the 'flow' init."""
    max_jump_m: float = 0.5
    """A tracked pose further than this from the prediction is a tracking loss."""
    max_jump_deg: float = 30.0
    """A rotation change beyond this is a tracking loss."""
    loss_jump: float = 4.0
    """Final loss above this multiple of the running median is a tracking loss."""
    keep: Literal["best", "last"] = "best"
    """'best': the pose of the lowest-loss iteration (the paper); 'last': the final pose
    (each loss is measured on different random pixels, so the lowest is partly luck)."""
    min_count: float = 0.0
    """Only pixels whose surface lies in a beta voxel with more than this many mapping samples count
    (0: all; when none qualifies, all do): unmapped space renders the initial sphere."""
    frontend: Literal["classical", "none", "auto"] = "none"
    """'classical': the feature frontend seeds each pose and checks the photometric one; 'none': the
    paper's tracking alone; 'auto': classical with `--priors stereo`, else none."""
    refine: Literal["all", "keyframes"] = "all"
    """With the frontend: 'all' refines every frame against the map; 'keyframes' only the frames that
    become keyframes (others keep the frontend's pose; frames without one are refined)."""
    rejected_keyframe: Literal["pass", "frontend"] = "pass"
    """With the frontend, a keyframe whose refined pose fails a check: 'pass' (lost, not mapped from;
    the slot passes on) or 'frontend' (keeps the frontend's pose and stays a keyframe)."""
    optimizer: Literal["adam", "gauss_newton"] = "adam"
    """'adam' on the L1 loss (the paper) or 'gauss_newton' (Levenberg-Marquardt with Huber
    weights: a few iterations, each a forward and three backward passes; `iters` is its maximum)."""
    residual: Literal["rgb", "grey"] = "rgb"
    """'gauss_newton': 'rgb' (three residuals per pixel, three backward passes) or 'grey'
    (the channels' mean: one backward pass)."""
    huber_delta: float = 0.05
    """Colour residuals beyond this get Huber's down-weighting ('gauss_newton' always; 'adam'
    with `huber`)."""
    huber: bool = False
    """'adam': Huber's loss (threshold `huber_delta`, L1's slope beyond it) instead of the
    paper's L1: for blur and rolling shutter, and smoother near the optimum."""
    affine_brightness: bool = False
    """Fit the frame's affine brightness (gain, bias) to the map's render in closed form at every
    iteration (`losses/brightness.py`) and compare the corrected render. Not in the paper."""
    brightness_prior: float = 1e-4
    """`affine_brightness`: ridge pull of the fit toward gain 1, bias 0, per unit of pixel weight
    (weak: a bound for pixels that barely constrain it, not a bias)."""
    max_gain: float = 4.0
    """`affine_brightness`: the fitted gain stays within [1 / max_gain, max_gain] of the map's: a
    render unlike the image would fit a gain near 0 and silence the pose's gradient."""
    damping: float = 1e-3
    """'gauss_newton': Levenberg-Marquardt damping on the normal equations' diagonal."""
    max_step_m: float = 0.05
    """'gauss_newton': a step translating more than this (metres) is shortened to it."""
    max_step_rad: float = 0.05
    """'gauss_newton': a step rotating more than this (radians) is shortened to it."""
    stop_m: float = 2e-4
    """'gauss_newton': stop once a step translates less than this (metres) ..."""
    stop_rad: float = 2e-4
    """... and rotates less than this (radians)."""
    average: int = 1
    """'gauss_newton': the pose is the mean of the last this many iterates (1: the last)."""
    lr_decay: float = 1.0
    """'adam': the learning rate falls geometrically to `lr * lr_decay` at the last step (1:
    constant). An option (docs/decisions.md)."""
    n_probe: int | None = None
    """Probe samples per ray while tracking (None: as in mapping)."""
    min_transmittance: float = 1e-4
    """Samples whose estimated transmittance is below this skip the network while tracking (no
    Eikonal term there); 0: every sample (docs/decisions.md)."""
    n_importance: int | None = None
    """Importance samples per ray while tracking (None: as in mapping)."""
    n_uniform: int | None = None
    """Stratified samples per ray while tracking (None: as in mapping)."""


@dataclass(frozen=True)
class FrontendConfig(Checked):
    """The classical frontend (`tracking.frontend = 'classical'`, `nicer_stream/frontend/`)."""

    where: ClassVar[str] = "frontend."

    max_side: int | None = 1280
    """The frontend works on the source's image up to this longer side (`Frame.detail`), not on the
    map's smaller one (None: the map's); docs/decisions.md."""
    features: Literal["sift", "klt"] = "sift"
    """'sift': SIFT keypoints matched to each track's latest descriptor; 'klt': Shi-Tomasi
    corners followed by pyramidal Lucas-Kanade (drifts on smooth texture: `frontend/sift.py`)."""
    corners: int = 1000
    """Features per frame (SIFT keypoints, or KLT corners kept alive); 400 lost the scale on a
    real camera (docs/decisions.md)."""
    min_distance_px: float = 8.0
    """KLT: minimum spacing of corners, pixels."""
    fb_px: float = 1.0
    """KLT: a track survives a frame when tracking back lands within this many pixels."""
    window: int = 40
    """Frames whose observations are kept (landmarks no frame in it sees are dropped)."""
    min_parallax_deg: float = 1.0
    """Triangulate a track once its two views' rays are this far apart."""
    guided_px: float = 10.0
    """A track with a landmark matches only keypoints this close to where a constant-velocity
    pose puts it (SIFT; 0: anywhere in the image)."""
    retriangulate_gain: float = 2.0
    """A landmark is triangulated again from a baseline giving this many times its parallax
    (0: never; landmarks then move only in the bundle adjustment)."""
    retriangulate_below_deg: float = 5.0
    """... while its parallax is below this many degrees (enough for ~2% depth at half a pixel)."""
    reproj_px: float = 2.0
    """Inlier threshold of PnP, triangulation and the BA's Huber loss, pixels."""
    min_inliers: int = 30
    """A PnP pose needs this many agreeing landmarks."""
    init_parallax_deg: float = 2.0
    """Without a depth prior, the SLAM starts once the first frame and the latest share tracks
    whose median parallax is this large (the essential matrix gives the second pose)."""
    fallback_parallax_deg: float = 0.0
    """... and when no held frame met it, the held frame with the widest median parallax above this
    (0: none, the first frame starts alone). Not a default (docs/decisions.md)."""
    start_ba: bool = True
    """Refine the start's two views by a bundle adjustment (the first view and the baseline's length
    held) before any other frame is posed against them (docs/decisions.md)."""
    prior_start: bool = True
    """With depth priors too, start from the frontend's two views, each prior fitted to their
    triangulated points; False, or where that fails: dense flow (`two_view_init`)."""
    ba_frames: int = 15
    """Frames in the local bundle adjustment (0: none): the latest trusted frames that each moved
    `ba_baseline_frac` from the one before; it runs whenever one joins."""
    ba_baseline_frac: float = 0.02
    """... of the median depth of the landmarks they see (every frame on the street at 1 m a
    frame, every ~4th on the Replica clip)."""
    ba_fixed: int = 3
    """Its oldest this many frames stay fixed (gauge and scale); with 1, the adjusted window is
    rescaled about that frame so its two oldest frames keep their distance (`hold_scale`)."""
    ba_iters: int = 10
    """Its Levenberg-Marquardt iterations at most."""
    max_disagreement_depth_frac: float = 0.005
    """Photometric and frontend poses further apart than this fraction of the landmarks' median depth
    (or `max_disagreement_frac` of the motion, if larger) are a tracking loss."""
    max_disagreement_frac: float = 0.3
    """See `max_disagreement_depth_frac`."""
    max_disagreement_deg: float = 2.0
    """Rotation bound of the same check, degrees."""
    evidence_ratio: float = 0.85
    """When they disagree, the pose whose loss against the map is below this times the other's is
    kept; within it, the one nearer the constant-velocity motion."""


@dataclass(frozen=True)
class StereoConfig(Checked):
    """`--priors stereo`: plane-sweep depth of each keyframe from its neighbouring keyframes."""

    where: ClassVar[str] = "stereo."

    window: int = 9
    """ZNCC window side, pixels (odd)."""
    max_side: int | None = 960
    """Sweep the source's larger image (`Frame.detail`) at this longer side, the depth averaged down
    to the map's pixels (None: the map's images); docs/decisions.md."""
    fusion_max_side: int | None = 640
    """`max_side` of the sweep a monocular prior is fitted to (`mono_fusion`); docs/decisions.md."""
    min_planes: int = 48
    """At least this many depth planes."""
    max_planes: int = 160
    """At most this many (cost grows linearly with them)."""
    min_texture: float = 0.005
    """A window whose grey-level std (0..1 units) is below this is untextured: not confident."""
    min_ncc: float = 0.9
    """The best ZNCC must reach this."""
    min_uniqueness: float = 0.0
    """The runner-up plane (2+ planes away) must cost this much more than the best."""
    max_plane_disagreement: int = 2
    """Partners that see a pixel must each put their own best plane within this many planes
    of the joint best."""
    scale: Literal["fixed", "fit"] = "fixed"
    """'fixed': the depth is in the poses' unit, its (w, q) fixed at (1, 0); 'fit': (w, q) refit
    per frame like a monocular prior's (absorbs a keyframe pair's baseline error)."""
    landmark_margin: float = 1.5
    """Depths searched: the frontend's landmarks' 2nd-98th percentiles, near / this and far * this;
    0: the scene bound's whole range (docs/decisions.md)."""
    min_landmarks: int = 30
    """Fewer landmarks than this in front of the keyframe: the scene bound's range."""
    target_baseline: float = 0.15
    """Partners (one earlier, one later frame) at the baseline nearest this fraction of the median
    landmark depth; 0: the nearest keyframes (docs/decisions.md)."""
    partner_frames: int = 10
    """Recent frames kept (images) as stereo partners besides the keyframes."""
    edge_window: int = 5
    """Depth-edge filter: a pixel whose window of known depths (this side) spans more than `edge_rel`
    is dropped; < 2: off (docs/decisions.md)."""
    edge_rel: float = 0.1
    """The span (relative to the nearest depth) the edge filter allows."""
    speckle_size: int = 400
    """Blobs of fewer pixels than this (at the sweep's size) are dropped (`drop_speckles`); 0: off."""
    speckle_step: float = 0.02
    """Neighbours belong to one blob where their inverse depths differ by at most this share
    of the median inverse depth."""
    fill_min_inliers: float = 0.7
    """Large holes are filled by the plane(s) at least this share of their rim lies on within 3%, with
    at most a tenth of it behind (`priors/plane_fill.py`); 0: off."""
    fill_planes: int = 1
    """Planes per hole: up to this many walls, each hole pixel taking the nearest (docs/decisions.md)."""
    normals: bool = False
    """Give keyframes a normal prior computed from the stereo depth; off, because it roughened the
    map (docs/decisions.md)."""
    fill_max_texture: float = 0.015
    """Only holes whose pixels are mostly untextured (grey-level std in a `window` square below this)
    are filled."""
    mono_fusion: bool = False
    """With a monocular provider: fit each keyframe's depth to its own stereo depth (a scale field and a
    shift, `priors/mono_alignment.py`), which fills the stereo's holes (docs/decisions.md)."""
    mono_cells: int = 7
    """Cells of that scale field across the image's longer side (docs/decisions.md)."""
    mono_smooth: float = 1e-4
    """Weight of the squared differences of neighbouring nodes, relative to the data term's
    (docs/decisions.md)."""
    mono_max_rel: float = 0.1
    """Stereo depth further than this share from the fitted monocular depth is replaced by it
    (`fuse_depth`); 0: off (docs/decisions.md)."""
    mono_veto_spread: float = 3.0
    """That share is at least this many robust spreads of the stereo's distance to the fit; 0:
    `mono_max_rel` alone (docs/decisions.md)."""


@dataclass(frozen=True)
class BoundConfig(Checked):
    """Scene bound used to normalise into [-1, 1]^3 (never from ground truth)."""

    where: ClassVar[str] = "bound."

    mode: Literal["auto", "config"] = "auto"
    """'auto' (SLAM: the first frame's scaled depth prior plus margin; mapping with known
    poses: a cube of `half_extent` in front of the cameras) or 'config' (centre, half_extent)."""
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Bound centre in the world (first camera) frame, metres, for mode 'config'."""
    half_extent: float = 4.0
    """Half side of the cube, metres, for mode 'config'."""
    margin: float = 1.5
    """Multiplier on the prior-derived extent (room for the unseen)."""
    max_depth_m: float = 8.0
    """Depths beyond this are ignored when estimating the bound."""
    camera_margin: float = 0.25
    """SLAM 'auto': the first camera at least this fraction of the half side inside the cube, which
    slides away from a near face as far as keeps the points inside; 0: centred (docs/decisions.md)."""
    points_edge: float = 0.05
    """With `camera_margin`: the points' 1-99 percentile box, grown by this fraction of its
    longest side, stays inside the cube."""


@dataclass(frozen=True)
class MeshConfig(Checked):
    """Mesh extraction."""

    where: ClassVar[str] = "mesh."

    resolution: int = 512
    """Marching-cubes grid resolution per axis."""
    visibility_margin_m: float = 0.1
    """Faces further than this behind every rendered depth map are culled (never seen), and
    so are faces this far in front of some rendered depth map (seen through: free space)."""
    measured_through_rel: float = 0.07
    """Faces further in front of a keyframe's measured stereo depth than this fraction of it are
    culled too (stereo runs only); 0: off (docs/decisions.md)."""


@dataclass(frozen=True)
class SlamConfig(Checked):
    """Everything a run needs; each component receives only its own part."""

    where: ClassVar[str] = ""

    preset: str = "paper"
    """Name of the preset this config started from."""
    max_side: int | None = None
    """Resize input so the longer side is at most this (None: native)."""
    model: ModelConfig = field(default_factory=ModelConfig)
    """Scene representation."""
    render: RenderConfig = field(default_factory=RenderConfig)
    """Rendering."""
    loss: LossConfig = field(default_factory=LossConfig)
    """Loss weights."""
    mapping: MappingConfig = field(default_factory=MappingConfig)
    """Mapping."""
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    """Tracking."""
    bound: BoundConfig = field(default_factory=BoundConfig)
    """Scene bound."""
    frontend: FrontendConfig = field(default_factory=FrontendConfig)
    """Classical frontend settings (used when `tracking.frontend = 'classical'`)."""
    stereo: StereoConfig = field(default_factory=StereoConfig)
    """Plane-sweep stereo priors (used with `--priors stereo`, and with monocular priors when
    `stereo.mono_fusion`)."""
    mesh: MeshConfig = field(default_factory=MeshConfig)
    """Mesh extraction."""
    seed: int = 0
    """Random seed."""


def paper() -> SlamConfig:
    """The paper's settings (Sec. 3.4 and the release's hyperparameters)."""
    return SlamConfig(preset="paper")


def fast() -> SlamConfig:
    """Sized for a 2-core CPU: 320 px images, fewer rays, samples and iterations. Where it departs
    from the paper for other reasons than cost, docs/decisions.md ("The `fast` preset") says why."""
    return SlamConfig(
        preset="fast",
        max_side=320,
        model=ModelConfig(color_levels=12, color_res_max=512, color_log2_table=17),
        render=RenderConfig(n_probe=32, n_importance=12, n_uniform=4, beta_count_weight=500.0),
        loss=LossConfig(weights=LossWeights(depth=10.0, flow=0.01, normal_l1=0.2, normal_angular=0.2)),
        mapping=MappingConfig(iters=60, first_iters=200, rays=1024, eikonal_points=256, batch_iters=350,
                              init="two_view", keyframes="view", keyframe_every=5, final_iters=100,
                              final_color_start=0.25, final_lr_end_factor=0.1),
        tracking=TrackingConfig(iters=20, rays=512, lr=3e-3, init="flow", keep="last", min_count=1000.0,
                                n_probe=32, n_importance=12, n_uniform=0, frontend="classical",
                                refine="keyframes", rejected_keyframe="frontend"),
        stereo=StereoConfig(mono_fusion=True),
        mesh=MeshConfig(resolution=192),
    )


PRESETS = {"paper": paper, "fast": fast}


def preset(name: str) -> SlamConfig:
    """A named preset; unknown names are a UserError."""
    if name not in PRESETS:
        raise UserError(f"unknown preset '{name}': use one of {', '.join(PRESETS)}")
    return PRESETS[name]()


def override(cfg: Any, values: dict[str, Any], where: str = "config", strict: bool = True) -> Any:
    """Return `cfg` with nested `values` applied; unknown keys raise UserError (`strict=False`
    skips them: a config saved by another version, whose renamed settings cannot matter)."""
    names = {f.name: f for f in fields(cfg)}
    changes = {}
    for key, val in values.items():
        if key not in names:
            if not strict:
                continue
            raise UserError(f"unknown key '{where}.{key}': valid keys are {', '.join(sorted(names))}")
        cur = getattr(cfg, key)
        if is_dataclass(cur):
            if not isinstance(val, dict):
                raise UserError(f"'{where}.{key}' must be a table of settings")
            changes[key] = override(cur, val, f"{where}.{key}", strict)
        else:
            changes[key] = tuple(val) if isinstance(val, list) else val
    return replace(cfg, **changes)


def load(preset_name: str, file: str | Path | None = None) -> SlamConfig:
    """Preset `preset_name`, optionally overridden by a .json or .toml file."""
    cfg = preset(preset_name)
    if file is None:
        return cfg
    path = Path(file)
    if not path.exists():
        raise UserError(f"config file {path} does not exist")
    text = path.read_text()
    kind = "TOML" if path.suffix == ".toml" else "JSON"
    try:  # TOMLDecodeError and JSONDecodeError are ValueErrors
        values = tomllib.loads(text) if kind == "TOML" else json.loads(text)
    except ValueError as e:
        msg = str(e).replace("\n", " ")
        raise UserError(f"config file {path} is not valid {kind} ({msg}): fix it or remove --config") from None
    if not isinstance(values, dict):
        raise UserError(f"config file {path} must hold a table of settings at the top level")
    try:
        return override(cfg, values)
    except UserError as e:
        raise UserError(f"config file {path}: {e}") from None


def to_dict(cfg: Any) -> dict:
    """Plain dict of a config (for summary.json)."""
    return dataclasses.asdict(cfg)
