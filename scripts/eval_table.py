"""A markdown table of the eval.json (and summary.json) of output directories, with the
bars of a reference directory (e.g. the known-pose `map` run) when given.

Usage: .venv/bin/python scripts/eval_table.py OUT [OUT ...] [--reference MAP_OUT] [--factor 1.3]
Depth and mesh columns are as eval.json holds them: under the ICP-refined alignment,
then under the trajectory's Sim(3) alone in brackets.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from nicer_stream.io import output_dir as od


def _cm(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.2f}"


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def row(out: Path) -> str:
    e = od.read_eval(out)
    s = od.read_summary(out) if (out / od.SUMMARY_FILE).is_file() else None
    m, p = e.mesh, e.mesh_pose_aligned
    wall = "-" if s is None else f"{s.wall_s:.0f}"
    return (f"| {out} | {_cm(e.ate_rmse_m)} | {_cm(e.depth_l1_m)} ({_cm(e.depth_l1_pose_aligned_m)}) | "
            f"{_cm(m.acc_m)} ({_cm(p.acc_m)}) | {_cm(m.comp_m)} ({_cm(p.comp_m)}) | "
            f"{_pct(m.comp_ratio)} ({_pct(p.comp_ratio)}) | {e.scene_alignment or '-'} | {wall} |")


def bars(ref: Path, factor: float) -> str:
    e = od.read_eval(ref)
    m = e.mesh
    return (f"| bars: {factor} x {ref} | <= 1.00 | <= {_cm(factor * e.depth_l1_m)} | <= {_cm(factor * m.acc_m)} | "
            f"<= {_cm(factor * m.comp_m)} | >= {_pct(m.comp_ratio / factor)} | | < 600 |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outs", nargs="+", type=Path)
    ap.add_argument("--reference", type=Path)
    ap.add_argument("--factor", type=float, default=1.3)
    a = ap.parse_args()
    print("| run | ATE cm | depth L1 cm | acc cm | comp cm | ratio | scene alignment | run s |")
    print("|---|---|---|---|---|---|---|---|")
    if a.reference:
        print(row(a.reference))
        print(bars(a.reference, a.factor))
    for out in a.outs:
        print(row(out))


if __name__ == "__main__":
    main()
