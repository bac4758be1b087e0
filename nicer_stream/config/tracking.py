"""The photometric tracker's section."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nicer_stream.config.checks import Checked


@dataclass(frozen=True)
class TrackingConfig(Checked):
    """Camera tracking (Sec. 3.3)."""

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
