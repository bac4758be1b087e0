"""A markdown table of the eval.json (and summary.json) of output directories, with the
bars of a reference directory (e.g. the known-pose `map` run) when given.

Usage: .venv/bin/python scripts/eval_table.py OUT [OUT ...] [--reference MAP_OUT] [--factor 1.3]
Depth and mesh columns are as eval.json holds them: under the ICP-refined alignment,
then under the trajectory's Sim(3) alone in brackets. "scale gap": the map's Sim(3) scale
(ICP) over the trajectory's, minus 1 (where they differ, the trajectory sits off the map).
With several OUTs a last row holds their means (seeds of one config: compare those means, the
runs of one seed move by more than most changes).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from nicer_stream.io import output_dir as od


def _cm(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.2f}"


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def values(out: Path) -> dict:
    """The table's numbers for one output directory (None where eval.json has none), and its
    scene alignment."""
    e = od.read_eval(out)
    s = od.read_summary(out) if (out / od.SUMMARY_FILE).is_file() else None
    m, p = e.mesh, e.mesh_pose_aligned
    gap = e.scene_scale / e.sim3_scale - 1 if e.scene_scale and e.sim3_scale else None
    return {"ate": e.ate_rmse_m, "depth": e.depth_l1_m, "depth_traj": e.depth_l1_pose_aligned_m,
            "acc": m.acc_m, "acc_traj": p.acc_m, "comp": m.comp_m, "comp_traj": p.comp_m,
            "ratio": m.comp_ratio, "ratio_traj": p.comp_ratio, "psnr": e.psnr_db, "gap": gap,
            "wall": None if s is None else s.wall_s, "alignment": e.scene_alignment or "-"}


def _db(x: float | None) -> str:
    return "-" if x is None else f"{x:.2f}"


def _row(name: str, v: dict) -> str:
    wall = "-" if v["wall"] is None else f"{v['wall']:.0f}"
    gap = "-" if v["gap"] is None else f"{100 * v['gap']:+.1f}%"
    return (f"| {name} | {_cm(v['ate'])} | {_cm(v['depth'])} ({_cm(v['depth_traj'])}) | "
            f"{_cm(v['acc'])} ({_cm(v['acc_traj'])}) | {_cm(v['comp'])} ({_cm(v['comp_traj'])}) | "
            f"{_pct(v['ratio'])} ({_pct(v['ratio_traj'])}) | {_db(v['psnr'])} | "
            f"{gap} | {v['alignment']} | {wall} |")


def row(out: Path) -> str:
    return _row(str(out), values(out))


def mean_row(vals: list[dict]) -> str:
    """Means over several runs' `values` of each number every one of them has."""
    mean = {k: (sum(v[k] for v in vals) / len(vals) if all(v[k] is not None for v in vals) else None)
            for k in vals[0] if k != "alignment"}
    return _row(f"mean of {len(vals)}", {**mean, "alignment": ""})


def bars(ref: Path, factor: float) -> str:
    e = od.read_eval(ref)
    m = e.mesh
    return (f"| bars: {factor} x {ref} | <= 1.00 | <= {_cm(factor * e.depth_l1_m)} | <= {_cm(factor * m.acc_m)} | "
            f"<= {_cm(factor * m.comp_m)} | >= {_pct(m.comp_ratio / factor)} | | | | < 600 |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outs", nargs="+", type=Path)
    ap.add_argument("--reference", type=Path)
    ap.add_argument("--factor", type=float, default=1.3)
    a = ap.parse_args()
    print("| run | ATE cm | depth L1 cm | acc cm | comp cm | ratio | PSNR dB | scale gap | scene alignment | run s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    if a.reference:
        print(row(a.reference))
        print(bars(a.reference, a.factor))
    vals = [values(out) for out in a.outs]  # each eval.json read once
    for out, v in zip(a.outs, vals):
        print(_row(str(out), v))
    if len(vals) > 1:
        print(mean_row(vals))


if __name__ == "__main__":
    from nicer_stream.errors import UserError
    try:
        main()
    except UserError as err:  # e.g. a run still going: one line, not a traceback
        raise SystemExit(f"error: {err}") from None
