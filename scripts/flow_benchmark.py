"""DIS flow vs ground-truth flow (GT depth + GT poses, the `oracle` flow) on small and large motion.

Usage (from the repository root): .venv/bin/python scripts/flow_benchmark.py [--max-side 320] [--per-pair]
Prints a markdown table; pixels of all pairs of a row are pooled (--per-pair: one row
per pair). The Replica rows are skipped (with a note on stderr) when ../shared/data is missing.
"""
from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nicer_stream.eval.flow import BAD_EPE_PX, flow_error_report
from nicer_stream.priors.dis_flow import DisFlowProvider
from nicer_stream.priors.oracle import OracleFlow
from nicer_stream.types import Frame
from sources import open_source
from sources.base import SourceOptions

REPLICA = Path("../shared/data/replica_room0_20f")


@dataclass(frozen=True)
class PairSet:
    label: str
    uri: str
    pairs: list[tuple[int, int]]


def pair_sets() -> list[PairSet]:
    # Synthetic room (120 frames, 320x240): one pair every 10 frames along the whole orbit,
    # consecutive (~2-6 px median GT flow) or 6 frames apart (~9-35 px).
    synth = "synthetic:room?frames=120"
    sets = [
        PairSet("synthetic room, consecutive", synth, [(i, i + 1) for i in range(0, 119, 10)]),
        PairSet("synthetic room, 6 apart", synth, [(i, i + 6) for i in range(0, 114, 10)]),
    ]
    if REPLICA.is_dir():
        # Replica moves less: consecutive is 0.6-2 px, and only 10 frames apart reaches ~10 px.
        uri = f"replica:{REPLICA}"
        sets += [
            PairSet("Replica room0, consecutive", uri, [(i, i + 1) for i in range(0, 19, 3)]),
            PairSet("Replica room0, 10 apart", uri, [(0, 10), (9, 19)]),
        ]
    else:
        print(f"note: {REPLICA} not found (run from the repository root): Replica rows skipped", file=sys.stderr)
    return sets


def load_frames(uri: str, indices: set[int], max_side: int) -> dict[int, Frame]:
    """The frames with these source indices, resized by the sources' max_side option."""
    out: dict[int, Frame] = {}
    for frame in open_source(uri, SourceOptions(max_side=max_side)):
        if frame.index in indices:
            out[frame.index] = frame
        if len(out) == len(indices):
            break  # synthetic frames are rendered lazily: stop once we have what we need
    return out


def run_set(ps: PairSet, max_side: int, per_pair: bool) -> list[str]:
    frames = load_frames(ps.uri, {i for p in ps.pairs for i in p}, max_side)
    dis, oracle = DisFlowProvider(), OracleFlow()
    dis.flow_both(frames[ps.pairs[0][0]], frames[ps.pairs[0][1]])  # warm-up: first-call costs are not per pair
    est, kept, gt, gt_valid, secs = [], [], [], [], []
    for a, b in ps.pairs:
        t0 = time.perf_counter()
        fw, _ = dis.flow_both(frames[a], frames[b])  # both directions: the mask needs the backward flow
        secs.append(time.perf_counter() - t0)
        ref = oracle.flow(frames[a], frames[b])
        for acc, x in ((est, fw.flow), (kept, fw.valid), (gt, ref.flow), (gt_valid, ref.valid)):
            acc.append(x)
    w, h = frames[ps.pairs[0][0]].width, frames[ps.pairs[0][0]].height
    if per_pair:
        groups = [(f"{ps.label} {a}->{b} ({w}x{h})", [k]) for k, (a, b) in enumerate(ps.pairs)]
    else:
        groups = [(f"{ps.label} ({w}x{h})", list(range(len(ps.pairs))))]
    rows = []
    for label, ks in groups:
        # Pool pixels of the pairs (the metrics are pixel-wise): stacking rows keeps (H, W, 2) shapes.
        r = flow_error_report(*(np.concatenate([x[k] for k in ks]) for x in (est, kept, gt, gt_valid)))
        bad_kept = "n/a" if r.n_bad == 0 else f"{r.bad_kept:.1%}"
        rows.append(
            f"| {label} | {len(ks)} | {r.gt_median_px:.1f} | {r.mean_epe:.3f} | {r.masked_epe:.3f} "
            f"| {r.bad_fraction:.3%} ({r.n_bad}) | {bad_kept} | {r.valid_fraction:.1%} "
            f"| {1e3 * np.mean([secs[k] for k in ks]):.1f} |"
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-side", type=int, default=320, help="resize frames to this longer side (pixels)")
    ap.add_argument("--per-pair", action="store_true", help="one row per pair instead of pooling each set")
    args = ap.parse_args(argv)
    print(f"DIS (medium) + consistency mask vs oracle GT flow; bad = EPE > {BAD_EPE_PX:g} px over GT-valid pixels.\n")
    print("| pairs | n | median GT flow (px) | mean EPE (px) | EPE in mask (px) | bad (n px) | bad kept by mask | mask keeps | ms/pair (fw+bw) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for ps in pair_sets():
        print("\n".join(run_set(ps, args.max_side, args.per_pair)), flush=True)


if __name__ == "__main__":
    main()
