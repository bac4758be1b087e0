"""`nicer-stream eval OUTDIR --source URI`: recompute OUTDIR/eval.json and print a table."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli.common import parse_drop, user_errors
from nicer_stream.errors import UserError
from nicer_stream.io import output_dir as od

_ROWS = [
    ("ATE RMSE Sim(3)", "ate_rmse_m", "m"),
    ("ATE RMSE SE(3)", "ate_se3_rmse_m", "m"),
    ("Sim(3) scale", "sim3_scale", ""),
    ("scene scale", "scene_scale", ""),
    ("RPE trans", "rpe_trans_m", "m"),
    ("RPE rot", "rpe_rot_deg", "deg"),
    ("depth L1", "depth_l1_m", "m"),
    ("depth L1, trajectory Sim(3)", "depth_l1_pose_aligned_m", "m"),
    ("PSNR", "psnr_db", "dB"),
    ("SSIM", "ssim", ""),
]
_MESH_ROWS = [
    ("mesh accuracy", "acc_m", "m"),
    ("mesh completion", "comp_m", "m"),
    ("completion ratio", "comp_ratio", ""),
    ("normal consistency", "normal_consistency", ""),
]


def _fmt(value: float | None, unit: str) -> str:
    return "-" if value is None else f"{value:.4f} {unit}".rstrip()


def format_table(rep: od.EvalReport) -> str:
    """Human-readable two-column table of an EvalReport (null shown as '-')."""
    rows = [(name, _fmt(getattr(rep, key), unit)) for name, key, unit in _ROWS]
    rows.append(("scene alignment", rep.scene_alignment or "-"))
    rows += [(name, _fmt(getattr(rep.mesh, key), unit)) for name, key, unit in _MESH_ROWS]
    rows += [(f"{name}, trajectory Sim(3)", _fmt(getattr(rep.mesh_pose_aligned, key), unit))
             for name, key, unit in _MESH_ROWS[:3]]
    rows.append(("mesh reference", rep.mesh.reference or "-"))
    v = rep.evaluated_views
    size = f" at {v.width}x{v.height}" if v.width else ""
    rows.append(("evaluated views", f"{len(v.frame_indices)}{size}"))
    h = rep.heldout
    rows += [("held-out PSNR", _fmt(h.psnr_db, "dB")), ("held-out SSIM", _fmt(h.ssim, "")),
             ("held-out depth L1", _fmt(h.depth_l1_m, "m")), ("held-out LPIPS", _fmt(h.lpips, "") if h.lpips is not None else "- (no weights)"),
             ("held-out views", f"{len(h.frame_indices)} (frames never mapped)")]
    rows.append(("priors", ", ".join(rep.priors) or "-"))
    w = max(len(r[0]) for r in rows)
    return "\n".join(f"{name:<{w}}  {val}" for name, val in rows)


@user_errors
def eval_cli(
    outdir: str = typer.Argument(..., help="Output directory of a run (trajectory.tum, mesh.ply, renders/, summary.json)."),
    source: str = typer.Option(None, "--source", help="Source URI with ground truth, e.g. replica:PATH (default: summary.json's)."),
    max_side: int = typer.Option(None, "--max-side", help="Resize frames so the longer side is at most N pixels."),
    stride: int = typer.Option(1, "--stride", help="Keep every N-th frame (as in the run)."),
    start: int = typer.Option(0, "--start", help="Skip this many frames first (as in the run)."),
    max_frames: int = typer.Option(None, "--max-frames", help="Stop after this many frames (as in the run)."),
    drop: str = typer.Option(None, "--drop", help="A:B drops input frames A..B-1 (as in the run)."),
) -> None:
    """Recompute eval.json for an output directory against a source's ground truth and print a table."""
    eval_command(Path(outdir), source, max_side=max_side, stride=stride, start=start, max_frames=max_frames,
                 drop=parse_drop(drop))


def eval_command(outdir: Path, source: str | None, **frames) -> od.EvalReport:
    """Evaluate `outdir` against source URI `source` (default: summary.json's `source`), write eval.json, print a table.
    `frames`: the SourceOptions that pick the run's frames (start, stride, drop, max_frames, max_side)."""
    # Heavy imports (torch, trimesh, sources) only once the command runs.
    from nicer_stream.eval.evaluate import evaluate_output_dir
    from sources import open_source
    from sources.base import SourceOptions

    if not outdir.is_dir():
        raise UserError(f"output directory {outdir} not found: give the OUTDIR of a 'nicer-stream run' or 'map'")
    if source is None:
        source = od.read_summary(outdir).source if (outdir / od.SUMMARY_FILE).is_file() else None
        if source is None:
            raise UserError("no --source given and summary.json names none: pass --source URI (e.g. replica:PATH)")
    src = open_source(source, SourceOptions(**frames))
    report = evaluate_output_dir(outdir, src, progress=lambda line: typer.echo(f"eval: {line}"))
    path = od.write_eval(outdir, report)
    typer.echo(format_table(report))
    typer.echo(f"wrote {path}")
    return report
