"""The mapping losses and the mapping optimiser's sections."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from nicer_stream.config.checks import Checked, check
from nicer_stream.losses.weights import LossWeights


@dataclass(frozen=True)
class LossConfig(Checked):
    """Mapping losses (Sec. 3.3)."""

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
