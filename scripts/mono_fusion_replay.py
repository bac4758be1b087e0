"""Replay `stereo.mono_fusion` on GT poses: the Replica clip's keyframes 0/5/10/15/19, each swept
against the frames 5 before and after it (3 on the missing side at the ends) at 640 px and
averaged to 320 px, and the `oracle` prior (realistic, or `--clean`) fitted to that depth.
Prints the depth L1 against GT (cm) and the share of pixels with a depth, per keyframe.

    .venv/bin/python scripts/mono_fusion_replay.py [--seed 0] [--clean | --field-cells 4] [--cells 5 7 9] [--smooth 1e-4] [--max-rel 0.1] [--spread 0 3]
"""
from __future__ import annotations

import argparse

import cv2
import numpy as np

from nicer_stream.config import StereoConfig
from nicer_stream.grey import to_grey_f32
from nicer_stream.priors.mono_alignment import align_depth, fuse_depth
from nicer_stream.priors.oracle import OracleCorruption, OracleDepthNormal
from nicer_stream.priors.plane_fill import fill_planar_holes
from nicer_stream.priors.stereo import local_std, shrink_depth, sweep_depth
from sources import open_source
from sources.base import SourceOptions

KEYFRAMES = (0, 5, 10, 15, 19)


def partners(k: int, n: int) -> list[int]:
    out = [p for p in (k - 5, k + 5) if 0 <= p < n]
    return out + ([k + 3] if k - 5 < 0 else [k - 3] if k + 5 >= n else [])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", default="replica:../shared/data/replica_room0_20f")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--clean", action="store_true", help="oracle:clean instead of the realistic oracle")
    ap.add_argument("--cells", type=int, nargs="+", default=[StereoConfig.mono_cells])
    ap.add_argument("--smooth", type=float, default=StereoConfig.mono_smooth)
    ap.add_argument("--max-rel", type=float, nargs="+", default=[StereoConfig.mono_max_rel])
    ap.add_argument("--spread", type=float, nargs="+", default=[StereoConfig.mono_veto_spread],
                    help="the veto's share at least this many robust spreads of the stereo around the fit (0: off)")
    ap.add_argument("--field-length", type=float, default=OracleCorruption.field_length_m,
                    help="length scale in metres of the realistic oracle's distortion field (shorter: a harder prior)")
    a = ap.parse_args()
    frames = list(open_source(a.source, SourceOptions(max_side=320, detail_side=1200)))
    params = StereoConfig()
    oracle = OracleDepthNormal(a.seed, OracleCorruption.clean() if a.clean else OracleCorruption(field_length_m=a.field_length))
    rows: dict[str, list[tuple[float, float]]] = {}
    for k in KEYFRAMES:
        f = frames[k]
        scale = 640 / max(f.detail.intrinsics.width, f.detail.intrinsics.height)
        intr = f.detail.intrinsics.scaled(scale)

        def grey(fr):
            return cv2.resize(fr.detail.grey, (intr.width, intr.height), interpolation=cv2.INTER_AREA)

        gt = f.gt_depth
        valid = gt > 0
        med = float(np.median(gt[valid]))
        d = sweep_depth(grey(f), f.gt_pose, [(grey(frames[p]), frames[p].gt_pose) for p in partners(k, len(frames))],
                        intr, 0.3 * med, 2.5 * med, params)
        d = shrink_depth(d, f.intrinsics.width, f.intrinsics.height)
        blank = local_std(to_grey_f32(f.rgb), params.window) < params.fill_max_texture
        mono = oracle.predict(f).depth

        def l1(x: np.ndarray) -> tuple[float, float]:
            m = valid & np.isfinite(x) & (x > 0)
            return 100 * float(np.abs(x[m] - gt[m]).mean()), float(m.mean())

        A = np.stack([mono[valid], np.ones(int(valid.sum()))], 1)
        w, q = np.linalg.lstsq(A, gt[valid], rcond=None)[0]
        out = {"stereo": l1(d),
               "stereo + planar fill (`--priors stereo`)": l1(fill_planar_holes(d, f.intrinsics, blank, min_inliers=params.fill_min_inliers)),
               "prior, its best affine fit to GT": l1(w * mono + q)}
        for c in a.cells:
            aligned = align_depth(mono, d, c, a.smooth)
            out[f"prior fitted to stereo ({c} cells), alone"] = l1(aligned)
            for r in a.max_rel:
                for k in a.spread:
                    out[f"fused, {c} cells, max_rel {r:g}, spread {k:g}"] = l1(fuse_depth(d, aligned, r, k))
        for name, v in out.items():
            rows.setdefault(name, []).append(v)
    what = "clean" if a.clean else f"field over {a.field_length} m"
    print(f"| depth (seed {a.seed}, {what}) | "
          + " | ".join(f"kf {k}" for k in KEYFRAMES) + " | mean |")
    print("|---" * (len(KEYFRAMES) + 2) + "|")
    for name, vs in rows.items():
        cells = " | ".join(f"{l:.2f} ({100 * s:.0f}%)" for l, s in vs)
        print(f"| {name} | {cells} | {np.mean([l for l, _ in vs]):.2f} ({100 * np.mean([s for _, s in vs]):.0f}%) |")


if __name__ == "__main__":
    main()
