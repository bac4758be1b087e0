"""A markdown table comparing the speed (and ATE) of a baseline run with newer runs of the
same command: `scripts/benchmarks.sh speedup` writes them.

Usage: .venv/bin/python scripts/speedup_table.py BASE_OUT NEW_OUT [NEW_OUT ...] [--labels BASE NEW ...]
Reads each directory's summary.json and eval.json (ATE '-' without one) and, when present,
time.txt: `/usr/bin/time -f "%e %M"` of the whole process (seconds, peak KB). `speedup` is
the baseline's s/frame over the row's.
"""
from __future__ import annotations

import argparse
from pathlib import Path

from nicer_stream.errors import UserError
from nicer_stream.io import output_dir as od

TIME_FILE = "time.txt"
HEADER = ("| commit | process s | wall_s | frames | s/frame | tracking s/frame | mapping s/frame | ATE cm | speedup |\n"
          "|---|---|---|---|---|---|---|---|---|")


def _f(x: float | None, fmt: str) -> str:
    return "-" if x is None else format(x, fmt)


def process_seconds(out: Path) -> float | None:
    """Wall seconds of the whole process (imports and evaluation included) from OUT/time.txt."""
    path = out / TIME_FILE
    if not path.is_file():
        return None
    try:
        return float(path.read_text().split()[-2])  # GNU time prints "Command exited ..." lines first on failure
    except (IndexError, ValueError):
        return None


def row(label: str, out: Path, base_spf: float) -> str:
    s = od.read_summary(out)
    ate = od.read_eval(out).ate_rmse_m if (out / od.EVAL_FILE).is_file() else None
    track, mapping = s.stats.get("tracking_s_per_frame"), s.stats.get("mapping_s_per_frame")
    speedup = base_spf / s.seconds_per_frame if s.seconds_per_frame > 0 else None
    return (f"| {label} | {_f(process_seconds(out), '.0f')} | {s.wall_s:.0f} | {s.frames} | {s.seconds_per_frame:.2f} | "
            f"{_f(track, '.2f')} | {_f(mapping, '.2f')} | {_f(None if ate is None else 100 * ate, '.2f')} | "
            f"{_f(speedup, '.2f')} |")


def table(outs: list[Path], labels: list[str]) -> str:
    """The header and one row per output directory; the first is the baseline."""
    base_spf = od.read_summary(outs[0]).seconds_per_frame
    return "\n".join([HEADER] + [row(lab, out, base_spf) for lab, out in zip(labels, outs)])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outs", nargs="+", type=Path, help="the baseline's output directory first")
    ap.add_argument("--labels", nargs="+", help="one per directory (default: the directory names)")
    a = ap.parse_args()
    if len(a.outs) < 2:
        ap.error("give the baseline's output directory and at least one other")
    labels = a.labels or [out.name for out in a.outs]
    if len(labels) != len(a.outs):
        ap.error(f"{len(labels)} labels for {len(a.outs)} directories")
    try:
        print(table(a.outs, labels))
    except UserError as e:
        raise SystemExit(f"error: {e}") from None


if __name__ == "__main__":
    main()
