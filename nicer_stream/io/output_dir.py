"""The output-directory contract: file names and the summary.json / eval.json schemas.

A run writes into OUT/:
- `trajectory.tum`  one line per input frame `t tx ty tz qx qy qz qw`, T_world_cam (io/trajectory.py)
- `mesh.ply`        final mesh with vertex colours
- `summary.json`    `Summary`
- `eval.json`       `EvalReport` (when GT exists)
- `renders/frame_NNNNNN.npz` (optional): `rgb` (H, W, 3) float32 [0, 1], `depth` (H, W)
  float32 z-depth [m], `normal` (H, W, 3) camera frame, `frame_index` int, `timestamp` float
  seconds (the frame's trajectory.tum time: `convert` matches renders to poses by it).
Scripts read these keys: keep them stable. Non-finite floats are written as null.
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from nicer_stream.errors import UserError

TRAJECTORY_FILE = "trajectory.tum"
MESH_FILE = "mesh.ply"
SUMMARY_FILE = "summary.json"
EVAL_FILE = "eval.json"
RENDERS_DIR = "renders"
DEPTH_PIXEL_RULE = "depth L1 on GT-valid pixels (gt > 0); rgb metrics on all pixels"


def render_name(frame_index: int) -> str:
    """File name of the render of frame `frame_index` inside RENDERS_DIR."""
    return f"frame_{frame_index:06d}.npz"


@dataclass
class StageSeconds:
    """Wall-clock seconds spent per stage."""

    tracking: float = 0.0
    """Tracking, including the frontend's share below."""
    frontend: float = 0.0
    """The classical frontend (KLT, PnP, triangulation, local BA): part of `tracking`."""
    mapping: float = 0.0
    priors: float = 0.0
    """Prior providers, and with `--priors stereo` the plane sweeps inside the SLAM."""
    sinks: float = 0.0


BOUND_SOURCES = ("config", "depth_prior", "cameras", "landmarks")


@dataclass
class Bound:
    """Scene bound: x_norm = (x_world - centre) / half_extent; `source` is 'config', 'depth_prior'
    or 'cameras' (known-pose mapping: a cube in front of the given cameras); never ground truth."""

    centre: list[float]
    half_extent: float
    source: str

    def __post_init__(self) -> None:
        if self.source not in BOUND_SOURCES:
            raise UserError(f"bound source must be one of {', '.join(BOUND_SOURCES)}, got '{self.source}'")


@dataclass
class Summary:
    """summary.json: what ran, how long, on what."""

    frames: int
    preset: str
    device: str
    priors: list[str]
    """Prior provider names; 'oracle' when GT-derived priors were used."""
    wall_s: float
    stages_s: StageSeconds
    seconds_per_frame: float
    peak_rss_mb: float
    versions: dict[str, str]
    interrupted: bool
    """True when a stop (Ctrl-C, SIGTERM) or an error ended the run before its last frame."""
    error: str | None = None
    """The one-line error that ended the run early, if one did."""
    bound: Bound | None = None
    notes: list[str] = field(default_factory=list)
    source: str | None = None
    """Source URI of the run (lets `nicer-stream eval` default --source)."""
    intrinsics: dict | None = None
    """{fx, fy, cx, cy, width, height} of the processed images (used by `convert`)."""
    config: dict | None = None
    """The full configuration the run used."""
    stats: dict = field(default_factory=dict)
    """Run-specific counters (iterations, tracking losses, dropped frames, ...)."""


@dataclass
class MeshReport:
    """Mesh metrics in metres; `reference` is 'gt_mesh' or 'gt_depth_points' (None when not computed)."""

    acc_m: float | None = None
    comp_m: float | None = None
    comp_ratio: float | None = None
    normal_consistency: float | None = None
    reference: str | None = None


@dataclass
class EvaluatedViews:
    """Which renders were compared: frame indices, their image size, and the pixel rule."""

    frame_indices: list[int] = field(default_factory=list)
    width: int | None = None
    height: int | None = None
    pixel_rule: str = DEPTH_PIXEL_RULE


@dataclass
class HeldOutReport:
    """Novel views: frames no mapping call fitted the map to, rendered from scene.pt at their
    tracked poses (eval/heldout.py). None (null) without such frames."""

    psnr_db: float | None = None
    ssim: float | None = None
    depth_l1_m: float | None = None
    """Under the same scene scale as the mapped views' depth L1."""
    lpips: float | None = None
    frame_indices: list[int] = field(default_factory=list)
    note: str = "LPIPS not computed: needs the lpips package and its AlexNet weights"


@dataclass
class EvalReport:
    """eval.json. None (null) for anything whose inputs were missing."""

    ate_rmse_m: float | None = None
    ate_se3_rmse_m: float | None = None
    rpe_trans_m: float | None = None
    rpe_rot_deg: float | None = None
    depth_l1_m: float | None = None
    psnr_db: float | None = None
    ssim: float | None = None
    priors: list[str] = field(default_factory=list)
    sim3_scale: float | None = None
    scene_scale: float | None = None
    """Scale of the Sim(3) that compares depth and meshes (`scene_alignment`)."""
    scene_alignment: str | None = None
    """'icp': the trajectory's Sim(3) (eval/trajectory.pose_sim3) refined by registering
    the mesh to the GT surface, as the paper evaluates monocular meshes; 'poses': the
    trajectory's Sim(3) alone (no mesh, no GT surface, one that cannot pin a similarity
    such as a single plane, or an ICP that changed the scale by more than 10%)."""
    depth_l1_pose_aligned_m: float | None = None
    """depth L1 under the trajectory's Sim(3) scale alone (equal to depth_l1_m with 'poses')."""
    evaluated_views: EvaluatedViews = field(default_factory=EvaluatedViews)
    mesh: MeshReport = field(default_factory=MeshReport)
    mesh_pose_aligned: MeshReport = field(default_factory=MeshReport)
    """The mesh metrics under the trajectory's Sim(3) alone, before registration."""
    heldout: HeldOutReport = field(default_factory=HeldOutReport)
    """The same image metrics on views the map was never fitted to."""


def _finite_or_null(x: Any) -> Any:
    """Recursively map non-finite floats to None (strict JSON has no inf/nan)."""
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, dict):
        return {k: _finite_or_null(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_finite_or_null(v) for v in x]
    return x


def _write_json(path: Path, data: dict) -> Path:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(json.dumps(_finite_or_null(data), indent=2, allow_nan=False) + "\n")
    tmp.replace(path)  # atomic: readers never see half a file
    return path


def _read_json(path: Path) -> dict:
    if not path.is_file():
        raise UserError(f"{path} not found: point at an output directory written by 'nicer-stream run' or 'map'")
    try:
        data = json.loads(path.read_text())
    except json.JSONDecodeError as e:
        raise UserError(f"{path} is not valid JSON ({e.msg} at line {e.lineno}): rewrite or delete it") from None
    if not isinstance(data, dict):
        raise UserError(f"{path} must hold a JSON object: rewrite or delete it")
    return data


def _build(cls, data: dict, path: Path):
    """cls(**known keys of data), the nested sections (`_NESTED`) built likewise; UserError naming
    the missing required keys."""
    names = {f.name for f in fields(cls)}
    known = {k: _build(_NESTED[k], v, path) if k in _NESTED and isinstance(v, dict) else v
             for k, v in data.items() if k in names}
    try:
        return cls(**known)
    except TypeError as e:
        raise UserError(f"{path}: {e} (missing or malformed keys): rewrite the file") from None


_NESTED = {"stages_s": StageSeconds, "bound": Bound, "evaluated_views": EvaluatedViews, "mesh": MeshReport,
           "mesh_pose_aligned": MeshReport, "heldout": HeldOutReport}


def write_summary(out_dir: str | Path, summary: Summary) -> Path:
    """Write OUT/summary.json; returns its path."""
    return _write_json(Path(out_dir) / SUMMARY_FILE, asdict(summary))


def read_summary(out_dir: str | Path) -> Summary:
    """Read OUT/summary.json (unknown keys ignored). Raises UserError if missing or malformed."""
    path = Path(out_dir) / SUMMARY_FILE
    return _build(Summary, _read_json(path), path)


def write_eval(out_dir: str | Path, report: EvalReport) -> Path:
    """Write OUT/eval.json; returns its path."""
    return _write_json(Path(out_dir) / EVAL_FILE, asdict(report))


def read_eval(out_dir: str | Path) -> EvalReport:
    """Read OUT/eval.json. Raises UserError if missing or malformed."""
    path = Path(out_dir) / EVAL_FILE
    return _build(EvalReport, _read_json(path), path)
