"""A markdown table comparing runs by their runtime (issue 15: async vs --sync): wall time,
frames per second, tracking / mapping seconds per frame, map versions, the latency from frame
read to pose event, and the accuracy (eval.json).

Usage: .venv/bin/python scripts/runtime_table.py OUT [OUT ...]
"""
from __future__ import annotations

import argparse
from pathlib import Path

from nicer_stream.io import output_dir as od


def row(out: Path) -> str:
    s = od.read_summary(out)
    st = s.stats
    e = od.read_eval(out) if (out / od.EVAL_FILE).is_file() else None

    def cm(x):
        return "-" if x is None else f"{100 * x:.2f}"

    acc = "-" if e is None else f"{cm(e.ate_rmse_m)} | {cm(e.depth_l1_m)} | {cm(e.mesh.acc_m)} / {cm(e.mesh.comp_m)} | {e.psnr_db if e.psnr_db is not None else float('nan'):.1f}"
    return (f"| {out.name} | {st.get('runtime', 'sync')} | {s.wall_s:.0f} | {s.frames / s.wall_s:.3f} | "
            f"{st['tracking_s_per_frame']:.2f} | {st['mapping_s_per_frame']:.2f} | {st.get('map_versions', '-')} | "
            f"{st.get('pose_latency_median_s', float('nan')):.1f} / {st.get('pose_latency_p95_s', float('nan')):.1f} | "
            f"{st.get('pose_latency_after_startup_median_s', float('nan')):.1f} / "
            f"{st.get('pose_latency_after_startup_p95_s', float('nan')):.1f} | {acc} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outs", nargs="+", type=Path)
    a = ap.parse_args()
    print("| run | runtime | wall s | fps | tracking s/f | mapping s/f | map versions | pose latency median / p95 s "
          "| after start-up | ATE cm | depth L1 cm | mesh acc / comp cm | PSNR dB |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for out in a.outs:
        print(row(out))


if __name__ == "__main__":
    main()
