"""How far the SLAM's start puts the first frame's depth-prior shift from the truth: the target
depth `(prior - q) / w` of Replica frame 0 against GT after an affine fit `GT = a * target + b`,
with `b` as a fraction of the median GT depth (a wrong shift bends the map: no similarity
removes it). Rows: each prior with the two-view start (frames 0 and 10, GT or DIS flow) and
with the first frame's normal prior alone.

Usage: .venv/bin/python scripts/shift_check.py
"""
from __future__ import annotations

import numpy as np

from nicer_stream.runtime.frame_priors import make_engine, map_frame
from nicer_stream.slam.first_map import first_scale_shift
from nicer_stream.slam.two_view import two_view_init
from sources import open_source
from sources.base import SourceOptions

MEDIAN_M = 2.0


def bend(frame, mf, wq) -> float:
    w, q = wq
    target = ((mf.depth_prior - q) / w).numpy()
    gt = frame.gt_depth
    m = gt > 0
    a, b = np.linalg.lstsq(np.stack([target[m], np.ones(m.sum())], 1), gt[m], rcond=None)[0]
    return 100 * b / float(np.median(gt[m]))


def main() -> None:
    frames = list(open_source("replica:../shared/data/replica_room0_20f", SourceOptions(max_side=320, max_frames=11)))
    print("| prior | shift from | b / median depth |\n|---|---|---|")
    for prior in ("oracle:clean", "oracle"):
        for flow in ("oracle", "dis"):
            engine = make_engine(prior, flow, "cpu")
            first = map_frame(frames[0], engine, [frames[10]], "cpu")
            second = map_frame(frames[10], engine, [frames[0]], "cpu")
            view = two_view_init(first, second, MEDIAN_M)
            got = f"{bend(frames[0], first, view.first_scale_shift):.1f}%" if view else "no start"
            print(f"| `{prior}` | two-view, {'GT' if flow == 'oracle' else 'DIS'} flow | {got} |")
        first = map_frame(frames[0], make_engine(prior, "oracle", "cpu"), [], "cpu")
        print(f"| `{prior}` | the normal prior | {bend(frames[0], first, first_scale_shift(first, MEDIAN_M)):.1f}% |")


if __name__ == "__main__":
    main()
