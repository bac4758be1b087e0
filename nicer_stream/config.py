"""Configuration: frozen dataclasses, one per component, and the named presets.

`paper` holds the paper's settings (Sec. 3, ../shared/paper); `fast` is sized
for a 2-core CPU. A JSON/TOML file may override any field by its nested name;
unknown keys are errors.
"""
from __future__ import annotations

import dataclasses
import json
import tomllib
from dataclasses import dataclass, field, fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from nicer_stream.errors import UserError
from nicer_stream.losses.weights import LossWeights


@dataclass(frozen=True)
class ModelConfig:
    """Hierarchical scene representation (Sec. 3.1)."""

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
    sphere_centre: str = "auto"
    """SLAM: where the initial sphere sits. 'bound': the bound's centre, radius `sphere_radius`;
    'camera': the first camera, radius the first frame's median depth (`loss.first_depth_median_m`);
    'auto': 'camera' when the first camera is not inside the bound-centred sphere, else 'bound'.
    A bound estimated from a distorted depth prior put the camera outside it (Replica, realistic
    oracle: |camera| = 1.03 > 0.9): every ray started inside the solid and the first mapping's
    depth term stayed flat for 180 of 300 iterations (held-out PSNR 26.7 -> 28.5 dB with 'camera')."""


@dataclass(frozen=True)
class RenderConfig:
    """Ray sampling and volume rendering (Sec. 3.2)."""

    n_probe: int = 640
    """Uniform samples per ray evaluated without gradient to place the others."""
    n_importance: int = 64
    """Importance samples per ray (with gradient)."""
    n_uniform: int = 32
    """Extra stratified samples per ray (with gradient)."""
    probe_stop_tau: float | None = 16.0
    """A ray's probes stop once its optical depth passes this (transmittance e^-16 = 1e-7:
    the weights skipped sum to less, and `render/probe.py` evaluates front to back in
    segments); None evaluates every probe. The same samples either way, computed faster."""
    min_transmittance: float = 0.0
    """With gradient: samples whose transmittance, estimated from the probes' SDF, is below this
    skip the network (`render/live_samples.py`: behind a surface, each adds less than this to
    its ray). 0: every sample goes through it. Mapping keeps 0: its samples behind surfaces
    also carry the Eikonal term (Replica, 1e-4: depth L1 3.2 -> 3.7-3.8 cm over three seeds);
    tracking sets its own (`TrackingConfig.min_transmittance`)."""
    keep_band_m: float = 0.0
    """With `min_transmittance`: samples within this distance behind a surface (estimated SDF
    above -keep_band_m) go through the network however little light reaches them, so the
    Eikonal term keeps its points there. 0: none kept for that. With 1e-4 and 0.1 m Replica runs were
    ~5% shorter (separate runs) but lost 1 dB of PSNR over five seeds, one map badly
    (docs/performance.md): an option, not a preset's."""
    near_m: float = 0.05
    """Closest sample distance from the camera, metres."""
    beta_mode: str = "adaptive"
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
    """Each mapping sample adds this to its voxel's count. With fewer rays and samples
    than the paper (8096 rays x ~98 samples), a weight of paper/ours keeps the same
    count-per-optimisation-effort curve."""
    chunk_rays: int = 2048
    """Rays per chunk when rendering whole images without gradient."""


@dataclass(frozen=True)
class LossConfig:
    """Mapping losses (Sec. 3.3)."""

    weights: LossWeights = field(default_factory=LossWeights)
    """Term weights (Eq. 12)."""
    warp_frames: int = 2
    """Other window frames each ray is warped into (warping and flow terms)."""
    metric_prior_alignment: bool = True
    """`map` (known poses): supervise depth with each frame's metric (w, q) from flow
    triangulation; False refits (w, q) by least squares every iteration (Eq. 10)."""
    slam_prior_alignment: str = "lstsq"
    """SLAM mapping: 'lstsq' refits each frame's depth-prior (w, q) every iteration (Eq. 10);
    'map' fits them once, to the depth the map renders when the frame is first mapped;
    'flow' fixes them at every mapping call by flow triangulation with the estimated poses."""
    first_depth_median_m: float = 2.0
    """Scale rule of the first SLAM mapping: the first frame's depth-prior median is taken
    as this many metres, its shift comes from the normal prior (`mapping/depth_shift.py`;
    the paper fixes w=20, q=0 for Omnidata's output range)."""
    affine_brightness: bool = False
    """Each mapped frame's affine brightness (gain exp(a), bias b; `losses/brightness.py`) is
    optimised with the map (`mapping/exposure.py`) and corrects the RGB and warping terms: a
    real camera's auto-exposure. The first frame mapped holds the gauge at (0, 0). Not in the paper."""
    huber_delta: float = 0.0
    """RGB and warping residuals: Huber-smoothed L1 with this threshold per channel
    (`losses/robust.py`), for blur and rolling shutter; 0: the paper's L1."""


@dataclass(frozen=True)
class MappingConfig:
    """Mapping optimiser and schedule (Sec. 3.3-3.4)."""

    iters: int = 100
    """Iterations per mapping call."""
    final_iters: int | None = None
    """Iterations of a closing mapping call in `finish()` over the last frame's window with
    the poses fixed, run even when that frame was just mapped; None: the paper's schedule
    (the last frame is mapped with `iters`, local BA included, unless it was just mapped)."""
    first_iters: int = 100
    """Iterations of the first mapping call (initialisation from the sphere)."""
    final_color_start: float | None = None
    """The `final_iters` call (poses fixed, no local BA): fraction of its iterations after
    which the colour grids join; None: at `ba_start`, as in the calls after the first (the
    first uses `batch_color_start`)."""
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
    keyframes: str = "stride"
    """'stride': a keyframe every `keyframe_every` frames, a mapping call every `every`; 'view': a
    keyframe when the view has changed (the keyframe_* thresholds below, `slam/keyframes.py`) and
    a mapping call at each keyframe, so mapping grows with what the camera saw, not with frames."""
    keyframe_min_overlap: float = 0.6
    """'view': a keyframe once fewer than this share of the last keyframe's tracks are still seen."""
    keyframe_max_baseline: float = 0.1
    """'view': ... or the camera moved this fraction of the scene's median depth from it."""
    keyframe_max_rotation_deg: float = 15.0
    """'view': ... or turned this many degrees from it."""
    keyframe_max_gap_s: float = 1.0
    """'view': ... or this many seconds passed (a camera that keeps changing slowly)."""
    full_res_keyframes: int = 64
    """Keyframes kept at full resolution in RAM (the newest, and the first); older ones are
    kept at half resolution without their flows (`MapFrame.halved`: ~1/6 of the memory), so a
    long sequence's memory grows slowly. 0: all at full resolution."""
    window_random: int = 5
    """Window frames drawn at random from all keyframes."""
    window_recent: int = 10
    """Window frames drawn from the latest `recent_pool` keyframes."""
    recent_pool: int = 20
    """Size of the recent-keyframe pool."""
    eikonal_points: int = 1024
    """Extra uniformly sampled points for the Eikonal term per iteration."""
    batched_terms: bool = True
    """Compute the loss terms for all window frames at once (`mapping/batched_objective.py`)
    when they share size and intrinsics; False: frame by frame (`mapping/objective.py`, the
    reference). The same terms either way."""
    init: str = "first_frame"
    """How the first mapping fixes scale and shift: 'first_frame' (at frame 0: the prior's
    shift from the normal prior, Sec. 3.4 otherwise), 'two_view' (wait for frame
    `init_frames`, take both poses and both priors' shifts from the flow between them;
    without a depth prior, from the frontend's tracks once their parallax suffices; the frames
    in between are tracked once the map exists) or 'auto' ('first_frame' when the first frame
    has a depth prior, else 'two_view')."""
    init_frames: int = 10
    """'two_view' with a depth prior: frames after the first that the second view waits for."""
    init_max_frames: int = 60
    """'two_view' without a depth prior (the frontend's start): frames held at most while the
    frontend's tracks grow to `frontend.init_parallax_deg` of parallax with the first frame. A
    slow camera or a 30 fps video needs more than `init_frames`: the synthetic room at 300 frames
    reached it at frame 11, and starting from the first frame alone at 10 cost its first 100
    frames' map 6x in depth L1 (docs/priors.md). Motion that never reaches it (forward
    motion) starts from the first frame once these are held."""
    batch_iters: int = 2000
    """Iterations of `nicer-stream map` (all frames in one window, known poses)."""
    batch_color_start: float = 0.25
    """`map` and the first SLAM mapping: fraction of iterations after which the colour
    grids join. One long call from the initial sphere replaces SLAM's many short ones,
    so the last quarter alone is too little (Replica map: PSNR 26.7 -> 30.7 dB)."""


@dataclass(frozen=True)
class TrackingConfig:
    """Camera tracking (Sec. 3.3)."""

    iters: int = 100
    """Iterations per frame."""
    rays: int = 1024
    """Pixels sampled afresh each iteration."""
    lr: float = 5e-3
    """Adam learning rate on the pose twist."""
    init: str = "constant_velocity"
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
    keep: str = "best"
    """'best': the pose of the lowest-loss iteration (the paper); 'last': the final pose
    (each loss is measured on different random pixels, so the lowest is partly luck)."""
    min_count: float = 0.0
    """Only pixels whose rendered surface point lies in a beta voxel with more than this
    many mapping samples count in the loss (0: all): unmapped space renders the initial
    sphere, whose colours pull the pose. None of the pixels qualifying: all are used."""
    frontend: str = "none"
    """'classical': a feature-track + PnP + local-BA frontend (`frontend` settings) seeds each
    frame's pose and checks the photometric result; 'none': the paper's tracking alone; 'auto':
    classical with `--priors stereo` (whose depth is only as good as the poses), else none."""
    refine: str = "all"
    """With the frontend on: 'all' refines every frame's pose against the map (the paper's
    tracking); 'keyframes' refines only the frames that become keyframes (they seed the map)
    and keeps the frontend's pose for the others. Frames the frontend has no pose for are
    refined either way."""
    rejected_keyframe: str = "pass"
    """With the frontend on, a keyframe slot whose refined pose fails a check: 'pass' (the frame
    is lost and not mapped from; with `refine = 'keyframes'` the slot passes to the next frame)
    or 'frontend' (the frame keeps the frontend's pose and stays a keyframe: with a weak map the
    passed-on slots can fail one after another, and the map then misses the rest of the path)."""
    optimizer: str = "adam"
    """'adam' on the L1 loss (the paper) or 'gauss_newton' (Levenberg-Marquardt with Huber
    weights: a few iterations, each a forward and three backward passes; `iters` is its maximum)."""
    residual: str = "rgb"
    """'gauss_newton': 'rgb' (three residuals per pixel, three backward passes) or 'grey'
    (the channels' mean: one backward pass)."""
    huber_delta: float = 0.05
    """Colour residuals beyond this get Huber's down-weighting ('gauss_newton' always; 'adam'
    with `huber`)."""
    huber: bool = False
    """'adam': Huber's loss (threshold `huber_delta`, L1's slope beyond it) instead of the
    paper's L1: for blur and rolling shutter, and smoother near the optimum."""
    affine_brightness: bool = False
    """Fit the frame's affine brightness (gain, bias) to the map's render at every iteration, in
    closed form (`losses/brightness.py`), and compare the corrected render: a real camera's
    exposure changes between frames. Not in the paper."""
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
    """'adam': the learning rate falls geometrically from `lr` to `lr * lr_decay` at the last step
    (1: constant). Replica, `oracle:clean`, five seeds (docs/performance.md): with
    `iters = 40` and 0.1, ATE 0.21 -> 0.19 cm, trajectory-aligned completion ratio 58 -> 73%,
    runs ~5% longer (separate runs); 0.3 at 20 iterations changed nothing; on the demo room (`stereo`, three
    seeds) ATE 0.63 -> 0.82 cm. Not a preset's."""
    n_probe: int | None = None
    """Probe samples per ray while tracking (None: as in mapping)."""
    min_transmittance: float = 1e-4
    """Samples behind surfaces whose estimated transmittance is below this skip the network
    while tracking (`render/live_samples.py`): each adds less than this to its ray's render and
    gradient, and tracking has no Eikonal term. 0: every sample."""
    n_importance: int | None = None
    """Importance samples per ray while tracking (None: as in mapping)."""
    n_uniform: int | None = None
    """Stratified samples per ray while tracking (None: as in mapping)."""


@dataclass(frozen=True)
class FrontendConfig:
    """The classical frontend (`tracking.frontend = 'classical'`, `nicer_stream/frontend/`)."""

    max_side: int | None = 1280
    """The frontend works on the source's image with its longer side up to this many pixels
    (`Frame.detail`), not on the map's smaller one (None: the map's). Its features then sit to a
    fraction of a map pixel: Replica clip, frontend alone, ATE 6.4 mm at 320 px -> 1.1 mm at
    1200 px; the KITTI drive 2.8 m at 320 px -> 0.47 m at 1241 (docs/priors.md). SIFT at 1200 x
    680 costs ~0.2 s a frame here."""
    features: str = "sift"
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
    """... and when no frame held for the start (`mapping.init_frames`) met that, take the held frame
    with the widest median parallax above this one among those with `min_inliers` essential-matrix
    inliers (0: none; the first frame then starts alone, without any depth). Forward motion loses
    its tracks before their parallax grows (KITTI at 320 x 97 px: 46 down to 15 inliers with frames
    1-10 at 0.6-1.3 degrees). Not a default: on the KITTI drive at 640 px, 0.5 gave ATE 0.68 / 0.71 /
    1.08 m on seeds 0-2 against 1.01 / 0.64 / 0.44 m without (docs/priors.md)."""
    start_ba: bool = True
    """Refine the start's two views (essential matrix, then triangulation) by a bundle adjustment
    with the first view and the baseline's length held, before any other frame is posed against
    them (`ClassicalFrontend._refine_pair`). Replica frames 0/10 at 1200 px: the second view 0.2 ->
    0.02 degrees from GT, its direction of travel 4.5 -> 0.4 degrees (docs/priors.md)."""
    prior_start: bool = True
    """With depth priors too, the two-view start is the frontend's (its tracks, adjusted by
    `start_ba`), each prior's scale and shift fitted to its triangulated points
    (`slam/two_view.py: two_view_from_tracks`); False, or where that fails: dense flow between
    the map's images (`two_view_init`)."""
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
    """Photometric and frontend poses further apart than this fraction of the landmarks' median
    depth (or than `max_disagreement_frac` of the frame's motion, whichever is larger) are a
    tracking loss: the frontend's pose is kept, the frame is not mapped from."""
    max_disagreement_frac: float = 0.3
    """See `max_disagreement_depth_frac`."""
    max_disagreement_deg: float = 2.0
    """Rotation bound of the same check, degrees."""
    evidence_ratio: float = 0.85
    """When they disagree, the pose whose photometric loss against the map is below this times
    the other's is kept; within it, the one nearer the constant-velocity motion
    (`slam/tracking_policy.py`)."""


@dataclass(frozen=True)
class StereoConfig:
    """`--priors stereo`: plane-sweep depth of each keyframe from its neighbouring keyframes."""

    window: int = 9
    """ZNCC window side, pixels (odd)."""
    max_side: int | None = 960
    """Sweep the source's larger image (`Frame.detail`, the frontend's) resized to this longer
    side where there is one, then average the depth down to the map's pixels (None: the map's
    images); above 640 px the window and the filters scale with it (`priors/stereo.py:
    scaled_to`). Replica clip, GT poses: L1 12.3 cm at 320 px -> 8.2 cm at 640 (5x the sweep's
    cost); with the stereo filters, keyframes 0/5/10/15/19: 640 / 960 / 1200
    px: 5.93 / 5.18 / 5.02 cm on 53.4 / 58.6 / 60.8% of the pixels, 0.6 / 1.3 / 2.3 s per sweep;
    SLAM runs, `--priors stereo`, seeds 0-2 (docs/priors.md): mesh accuracy 5.75 /
    5.18 / 6.04 cm. The monocular fusion sweeps at `fusion_max_side` instead."""
    fusion_max_side: int | None = 640
    """`max_side` of the sweep a monocular prior is fitted to (`mono_fusion`). Replica clip,
    realistic `oracle`, seeds 0-2: at 960 the ICP-aligned mesh was as good (3.66 / 2.54 cm against
    3.72 / 2.47) but the trajectory-aligned one worse (4.99 / 4.21 cm, 69% against 4.06 / 2.84 cm,
    87%: a scale gap of +1.0% against -0.2%), and the sweeps cost 10-13 s more per run."""
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
    scale: str = "fixed"
    """'fixed': the depth is in the poses' unit, its (w, q) fixed at (1, 0); 'fit': (w, q) refit
    per frame like a monocular prior's (absorbs a keyframe pair's baseline error)."""
    landmark_margin: float = 1.5
    """The depths searched are those of the frontend's landmarks in the keyframe (2nd to 98th
    percentile), near divided and far multiplied by this; 0 searches the scene bound's whole
    range. A sweep that starts near the camera finds false matches there (synthetic room, GT
    poses: near 0.1 m -> 17-25% of the confident pixels >10% off, near 0.5 m -> 7-8%)."""
    min_landmarks: int = 30
    """Fewer landmarks than this in front of the keyframe: the scene bound's range."""
    target_baseline: float = 0.15
    """Partners (one earlier, one later frame) are chosen with a baseline nearest this fraction
    of the keyframe's median landmark depth, among the keyframes and the last `partner_frames`
    frames; 0 takes the nearest keyframes. The window matching degrades with the viewing angle
    (synthetic room, GT poses, keyframe 30: partners 3 / 5 / 8 frames away, baselines ~0.13 /
    0.2 / 0.3 of the depth: 2.3% / 5.9% / 17% of the confident pixels >10% off). 0.15 rather
    than 0.1: on a SLAM run's own poses (1-3 cm apart from GT between partners) 0.1 / 0.15 / 0.2
    left 14.8% / 10.6% / 9.6% of them >10% off (every keyframe; GT poses: 2.8% / 3.3%)."""
    partner_frames: int = 10
    """Recent frames kept (images) as stereo partners besides the keyframes."""
    edge_window: int = 5
    """Depth-edge filter (`drop_depth_edges`): a pixel whose edge_window-square neighbourhood (at
    the sweep's size) of known depths spans more than `edge_rel` is dropped; < 2: off. Replica,
    GT poses, 640 px: L1 8.2 -> 5.3 cm with `speckle_size`, confident pixels 74 -> 61%
    (without speckles: edge_window 7: 4.3 cm, 54%; 9: 3.5 cm, 47%)."""
    edge_rel: float = 0.1
    """The span (relative to the nearest depth) the edge filter allows."""
    speckle_size: int = 400
    """Blobs of fewer pixels than this (at the sweep's size) are dropped (`drop_speckles`); 0: off."""
    speckle_step: float = 0.02
    """Neighbours belong to one blob where their inverse depths differ by at most this share
    of the median inverse depth."""
    fill_min_inliers: float = 0.7
    """Large holes (untextured walls) are filled by the plane(s) their rim's known depths fit,
    where at least this share of the rim lies on them within 3% of its depth, and at most a tenth
    of the rim lies behind a plane (a foreground surface's plane is not a wall bounding the hole;
    `priors/plane_fill.py`); 0: off."""
    fill_planes: int = 1
    """Planes per hole: up to this many walls, each hole pixel taking the nearest (a blank room
    corner). Replica, GT poses, keyframes 0/5/10/15/19: pixels with a
    depth 61.7% (one plane within 2%, no test of what lies behind) -> 64.7% (1) / 71.1%
    (3), depth L1 5.58 -> 5.58 / 5.56 cm (filled pixels at 2.2 / 3.5 cm); SLAM runs, seeds 0-2 (docs/priors.md): mesh
    accuracy 6.69 -> 5.75 / 5.75 cm, depth L1 6.90 -> 6.65 / 7.41 cm, PSNR 31.22 -> 31.36 / 30.48 dB:
    on the runs' own poses the rims are noisier and a second plane is more often wrong."""
    normals: bool = False
    """Give keyframes a normal prior computed from the stereo depth. Off: those normals come
    from noisy, partly filled depth, and the normal loss on them roughened the map (Replica,
    seed 0: depth L1 7.8 -> 6.8 cm, mesh 6.9 / 5.9 (67%) -> 6.6 / 5.2 cm (75%) without them)."""
    fill_max_texture: float = 0.015
    """Only holes whose pixels are mostly untextured are filled: grey-level std (0..1) in a
    `window` square at the map's size below this (Replica's blank walls: median 0.011-0.012;
    the synthetic room's occlusion holes: 0.019-0.056)."""
    mono_fusion: bool = False
    """With a monocular depth provider (`oracle`, `omnidata`, `depth-anything`, `cache:`): sweep
    the keyframes as `--priors stereo` does and fit each keyframe's monocular depth to its stereo
    depth (`priors/mono_alignment.py`: a bilinear scale field over `mono_cells` cells plus one
    shift), the stereo's holes (and its pixels far from the fit, `mono_max_rel`) filled from the
    fitted monocular depth, (w, q) then (1, 0); its
    normal prior stays the provider's. Off (the paper): the monocular depth alone, its (w, q)
    fitted per frame. Replica clip, GT poses, realistic `oracle`, keyframes 0/5/10/15/19: depth
    L1 19.1 cm (the prior after its best affine fit to GT) -> 6.4 cm on every pixel (the stereo
    alone: 5.9 cm on 53% of them)."""
    mono_cells: int = 7
    """Cells of the scale field across the image's longer side (8 x 6 nodes at 4:3). Replica, GT
    poses, realistic oracle seed 0 (`scripts/mono_fusion_replay.py --cells 5 7 9`): L1 7.95 /
    6.34 / 6.33 cm."""
    mono_smooth: float = 1e-4
    """Weight of the squared differences of neighbouring nodes (relative to the data term's;
    `align_depth`). Replica, GT poses, 7 cells, stereo kept wherever known, oracle seeds 0 / 1:
    1e-3: 7.3 / 8.1 cm, 1e-4: 6.7 / 6.8 cm, 1e-5: 7.4 / 7.2 cm."""
    mono_max_rel: float = 0.1
    """Stereo depth more than this share away from the fitted monocular depth is replaced by
    it (`fuse_depth`: stereo's gross errors); 0: off. Replica, GT poses, oracle seeds 0 / 1
    (`scripts/mono_fusion_replay.py --max-rel 0 0.05 0.1 0.2`): 0: 6.62 / 6.86 cm; 0.05: 6.55 /
    6.76; 0.1: 6.34 / 6.58; 0.2: 6.50 / 6.75. `oracle:clean`, seed 0: 4.97 -> 4.37 cm at 0.1."""
    mono_veto_spread: float = 3.0
    """The veto's share is at least this many robust spreads of the stereo's relative distance
    to the fit (`fuse_depth`'s `spread_k`); 0: `mono_max_rel` alone. Replica, GT poses, seeds 0 /
    1 (`scripts/mono_fusion_replay.py --seed S [--field-cells N] --spread 0 3`): unchanged for `oracle` (3 x 3.2% < 10%: 6.33 / 6.58 cm) and
    `oracle:clean`; a prior whose distortion varies over 8 / 16 cells (finer than the fit): 10.20
    / 10.35 -> 9.89 / 10.07 cm and 11.78 / 11.32 -> 10.80 / 10.53 cm (stereo kept wherever known:
    9.89 / 10.19, 10.71 / 10.43). SLAM, Replica, `oracle`, seeds 0-2: every metric unchanged to
    the digit (the spread stayed below a third of 10% on every keyframe)."""


@dataclass(frozen=True)
class BoundConfig:
    """Scene bound used to normalise into [-1, 1]^3 (never from ground truth)."""

    mode: str = "auto"
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
    """SLAM with 'auto': the first camera(s) at least this fraction of the half side inside the
    cube; where one is nearer a face (a first frame's points lie in front of it, so centred on
    them the cube starts at the camera), the cube slides away from that face, as far as keeps the
    points (see `points_edge`) inside. 0: centred on the points (the demo
    room's back wall then fell outside the cube). Mapping with known poses keeps the cube centred on
    every frame's points."""
    points_edge: float = 0.05
    """With `camera_margin`: the points' 1-99 percentile box, grown by this fraction of its
    longest side, stays inside the cube."""


@dataclass(frozen=True)
class MeshConfig:
    """Mesh extraction."""

    resolution: int = 512
    """Marching-cubes grid resolution per axis."""
    visibility_margin_m: float = 0.1
    """Faces further than this behind every rendered depth map are culled (never seen), and
    so are faces this far in front of some rendered depth map (seen through: free space)."""
    measured_through_rel: float = 0.07
    """Faces further in front of some keyframe's measured stereo depth than this fraction of
    it are culled too (that measurement saw through them); 0: off. Runs with plane-sweep
    stereo only (`--priors stereo`, or `stereo.mono_fusion`). At 0.05 the demo room's mesh
    completion rose 4.60 -> 5.27 cm; at 0.07 it stays, and Replica's `stereo` accuracy falls
    5.18 -> 4.65 cm (0.1: 4.79; docs/priors.md)."""


@dataclass(frozen=True)
class SlamConfig:
    """Everything a run needs; each component receives only its own part."""

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
    """Sized for a 2-core CPU: 320 px images, fewer rays, samples and iterations."""
    return SlamConfig(
        preset="fast",
        max_side=320,
        model=ModelConfig(color_levels=12, color_res_max=512, color_log2_table=17),
        # Count weight 500: at 1024 rays x 16 samples the paper's c1 would leave beta at c0
        # (4 cm here) for the whole clip; with it, well-observed voxels reach ~1 cm.
        render=RenderConfig(n_probe=32, n_importance=12, n_uniform=4, beta_count_weight=500.0),
        # Depth and normals weigh more than Eq. 12's: those weights were set for Omnidata's
        # relative depth at 1200 px; at 320 px they left depth to the RGB terms and the
        # surfaces where the initial sphere put them (Replica map, oracle: depth L1 13 cm ->
        # 4.6 cm, PSNR 26 -> 31 dB with batch_color_start). Depth 10 rather than 1: a 3 cm
        # depth error costs only 1e-3 of squared metres against RGB L1 ~0.04, so at weight 1
        # the SLAM map settled ~9 cm deep at near range (`0.97 * target + 8.7 cm`), tracking
        # then stretched the path by 6% (Replica run: depth L1 14.7 -> 3.2 cm).
        loss=LossConfig(weights=LossWeights(depth=10.0, flow=0.01, normal_l1=0.2, normal_angular=0.2)),
        # Two-view start: the first frame's shift from the normal prior alone is ~2% of the
        # median depth off, which bent the Replica map into `0.72 * true + 13 cm` (oracle:clean).
        # With DIS flow the two-view's shift is worse than the normals' and `two_view_init`'s
        # checks hand the start to the first frame (slam/two_view.py, docs/priors.md).
        # 'auto' (the first frame's start whenever it has a depth prior) gives better maps with
        # realistic priors but worse trajectories (docs/priors.md, "The start with a depth prior"):
        # Replica, realistic `oracle`: depth L1 71 -> 10.8 cm, ATE 0.39 -> 1.54 cm; `oracle:clean`:
        # ATE 0.28 -> 4.58 cm.
        # Keyframes every 5 frames and a 150-iteration closing call with fixed poses: the Replica
        # map is then fitted to frames 0/5/10/15/19 together at the end rather than to 0/10 plus
        # the latest (oracle, seeds 0-2, ICP-aligned mesh completion 1.56-2.22 -> 1.56-1.73 cm).
        # With local BA in the closing call the map got worse (seed 0: completion 1.84 -> 2.40 cm).
        # Halving the iterations (to 40/150/80, tracking 60 -> 20) made the Replica run 2.1x faster
        # (ATE 0.28 -> 0.68 cm, depth and mesh alike, PSNR 30.7 -> 27.6 dB) but the demo room's ATE
        # 1.7 -> 4.9 cm, mesh accuracy 4.2 -> 5.2 cm: kept at the measured schedule.
        # The closing call is a refinement with fixed poses: its learning rates fall on a cosine
        # to 0.1x and the colour grids join at a quarter (not at `ba_start`). That buys back
        # the map a shorter schedule loses: 200/60/100 instead of 300/80/150, Replica (realistic
        # `oracle`, seed 0) 108 -> 88 s, mesh 3.74 / 2.51 -> 3.65 / 2.30 cm, depth L1 3.80 -> 3.98
        # cm, PSNR 31.47 -> 30.45 dB (seeds 0-2: 0.5 dB less PSNR, the mesh better); the demo room
        # 185 -> 151 s, seed 0 better on every metric, seed 1 mixed (docs/performance.md).
        mapping=MappingConfig(iters=60, first_iters=200, rays=1024, eikonal_points=256, batch_iters=350,
                              init="two_view", keyframe_every=5, final_iters=100,
                              final_color_start=0.25, final_lr_end_factor=0.1),
        # Tracking (Replica run, oracle priors): started from a PnP pose on the flow prior and the
        # map's rendered depth. From the previous pose (as the release does) 60 RGB iterations
        # recovered only part of each motion: translations ~10% short, the map 9% too deep
        # for its own path; the constant-velocity guess compounded that into a run-away (ATE
        # 3.2 cm). PnP alone (0 iterations) drifted (ATE 2.2 cm): the RGB refinement stays.
        # The last iterate rather than the lowest of 512-pixel losses measured on different
        # pixels; only pixels ending in mapped voxels.
        # The classical frontend seeds every pose and only keyframes are refined against the map,
        # with 20 Adam iterations (a keyframe whose refinement fails keeps the frontend's pose).
        # Measured (docs/performance.md, `oracle:clean`): Replica clip, seeds 0-2, ATE
        # 0.22-0.26 cm, mesh 2.84-2.95 / 1.75-1.91 cm, PSNR 29.5-30.6 dB, seed 0 in 144 s where refining
        # every frame with 60 iterations took 477 s (ATE 0.30 cm); demo room ATE 0.79 cm, mesh
        # 3.54 / 2.81 cm against 0.75 cm and 4.46 / 3.39 cm refining every frame. The frontend alone
        # drifts on the room (ATE 4.0 cm): the keyframes' refinement stays.
        tracking=TrackingConfig(iters=20, rays=512, lr=3e-3, init="flow", keep="last", min_count=1000.0,
                                n_probe=32, n_importance=12, n_uniform=0, frontend="classical",
                                refine="keyframes", rejected_keyframe="frontend"),
        # A monocular prior fitted to the keyframes' own stereo depth (priors/mono_alignment.py).
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
    return override(cfg, values)


def to_dict(cfg: Any) -> dict:
    """Plain dict of a config (for summary.json)."""
    return dataclasses.asdict(cfg)
