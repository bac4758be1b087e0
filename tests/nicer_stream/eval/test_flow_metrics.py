"""Flow metrics in closed form, and DIS against GT flow (depth + poses) on the synthetic room."""
from __future__ import annotations

import math

import numpy as np
import pytest

from nicer_stream.eval.flow import end_point_error, epe_map, flow_error_report
from nicer_stream.priors.dis_flow import DisFlowProvider
from nicer_stream.priors.flow_consistency import consistency_mask
from nicer_stream.priors.oracle import OracleFlow
from sources import open_source
from sources.base import SourceOptions

SYNTH = "synthetic:room?frames=120"


def test_identical_flows_have_zero_error():
    f = np.random.default_rng(0).normal(size=(4, 5, 2)).astype(np.float32)
    assert end_point_error(f, f) == 0.0
    r = flow_error_report(f, np.ones((4, 5), bool), f, np.ones((4, 5), bool))
    assert r.mean_epe == r.masked_epe == r.bad_fraction == 0.0 and r.n_bad == 0
    assert math.isnan(r.bad_kept)  # no bad pixel: undefined, not "all removed"


def test_constant_offset_gives_its_length():
    gt = np.zeros((3, 4, 2), np.float32)
    assert end_point_error(gt + np.array([3.0, 4.0], np.float32), gt) == pytest.approx(5.0)
    assert epe_map(gt + np.array([0.0, -2.0], np.float32), gt) == pytest.approx(np.full((3, 4), 2.0))


def test_masks_select_pixels():
    gt = np.zeros((2, 4, 2), np.float32)
    flow = gt.copy()
    flow[:, :2, 0] = 10.0  # left half 10 px off, right half exact
    left = np.zeros((2, 4), bool)
    left[:, :2] = True
    assert end_point_error(flow, gt, left) == pytest.approx(10.0)
    assert end_point_error(flow, gt, ~left) == 0.0
    assert math.isnan(end_point_error(flow, gt, np.zeros((2, 4), bool)))
    gt_valid = np.ones((2, 4), bool)
    gt_valid[0, 0] = False  # a GT-invalid bad pixel counts nowhere
    kept = ~left
    kept[1, 0] = True  # the mask keeps one of the 3 remaining bad pixels
    r = flow_error_report(flow, kept, gt, gt_valid)
    assert r.n_bad == 3 and r.bad_fraction == pytest.approx(3 / 7) and r.bad_kept == pytest.approx(1 / 3)
    assert r.mean_epe == pytest.approx(30 / 7) and r.masked_epe == pytest.approx(10 / 5)
    assert r.valid_fraction == pytest.approx(5 / 8) and r.gt_median_px == 0.0
    with pytest.raises(ValueError):
        epe_map(flow, gt[:, :3])


def _dis_vs_gt(start: int, gap: int, boundary: bool = True):
    """DIS on synthetic-room frames (start, start + gap) at 320x240 vs the oracle GT flow.

    boundary=False scores the forward/backward round trip alone (no motion-boundary rule).
    """
    a, b = open_source(SYNTH, SourceOptions(start=start, stride=gap, max_frames=2, max_side=320))
    ref = OracleFlow().flow(a, b)
    fw, bw = DisFlowProvider().flow_both(a, b)
    kept = fw.valid if boundary else consistency_mask(fw.flow, bw.flow, boundary=False)
    return flow_error_report(fw.flow, kept, ref.flow, ref.valid)


def test_dis_small_motion_synthetic():
    """Frames 40 -> 41 (4.1 px median GT flow); measured: EPE 0.18 px, no pixel > 3 px, mask keeps 94.5%.

    With no bad pixel the "mask removes > 3 px errors" check is vacuous here; see the next tests.
    The coverage check guards the motion-boundary rule: on small motion it must not eat the mask
    (95.7% without it).
    """
    r = _dis_vs_gt(40, 1)
    print(r)
    assert 2.0 < r.gt_median_px < 6.0
    assert r.mean_epe < 0.4 and r.masked_epe <= r.mean_epe
    assert r.bad_fraction < 0.005
    assert r.valid_fraction > 0.8


def test_dis_large_motion_synthetic_mask_removes_bad_pixels():
    """Frames 30 -> 36 (19 px median): DIS fails on 13% of pixels (EPE 3.0 px), the mask keeps 3.5% of them.

    Measured: masked EPE 0.36 px, mask keeps 61% of the pixels (the round trip alone: 12%, 0.52 px, 73%).
    """
    r = _dis_vs_gt(30, 6)
    print(r)
    assert r.gt_median_px > 10.0 and r.bad_fraction > 0.05  # hard enough for the mask to matter
    assert r.mean_epe < 6.0 and r.masked_epe < 0.6
    assert r.bad_kept < 0.1
    assert r.valid_fraction > 0.5


@pytest.mark.parametrize("start", [0, 20, 60])
def test_dis_moderate_motion_synthetic_mask_removes_bad_pixels_at_motion_boundaries(start):
    """Frames (i, i + 6) with 9-17 px median flow and 1-4% bad pixels, mostly next to depth edges.

    There DIS smears the foreground's flow onto the background consistently in both directions,
    so the round trip alone keeps about half of the > 3 px pixels (measured: 0->6 53%, 20->26 46%,
    60->66 68%); the motion-boundary rule brings that to 4.5%, 10% and 17%, the mask still
    keeping 86%, 79% and 78% of the pixels (scripts/flow_benchmark.py --per-pair).
    """
    r = _dis_vs_gt(start, 6)
    rt = _dis_vs_gt(start, 6, boundary=False)
    print(f"{start}->{start + 6}: {r}\n  round trip only: {rt}")
    assert 8.0 < r.gt_median_px < 18.0 and r.n_bad > 300  # moderate motion, enough bad pixels to count
    assert r.bad_kept < 0.3
    assert r.bad_kept < 0.5 * rt.bad_kept
    assert r.masked_epe <= rt.masked_epe  # removing them does not make the kept flow worse
    assert r.valid_fraction > 0.7
