"""The labelled oracle priors: the realistic default (a monocular network's errors), the near-GT
`oracle:clean`, and GT flow."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from nicer_stream.errors import UserError
from nicer_stream.priors import make_depth_normal_provider
from nicer_stream.geometry.depth_normals import normals_from_depth, view_rays
from nicer_stream.priors.oracle import (
    OracleCorruption,
    OracleDepthNormal,
    OracleFlow,
    fill_invalid_nearest,
    flow_from_depth_pose,
)
from nicer_stream.types import Frame, Intrinsics


def test_clean_oracle_depth_is_affine_in_gt_depth(replica_small):
    provider = OracleDepthNormal(seed=3, corruption=OracleCorruption.clean())
    scales = []
    for frame in replica_small:
        out = provider.predict(frame)
        gt = fill_invalid_nearest(frame.gt_depth)
        assert out.depth.shape == gt.shape and out.depth.dtype == np.float32
        A = np.stack([gt.ravel(), np.ones(gt.size)], 1).astype(np.float64)
        (s, t), *_ = np.linalg.lstsq(A, out.depth.ravel().astype(np.float64), rcond=None)
        rel_rms = np.sqrt(np.mean((A @ [s, t] - out.depth.ravel()) ** 2)) / np.median(out.depth)
        assert 0.45 < s < 2.1 and rel_rms < 0.05, (s, t, rel_rms)
        assert rel_rms > 1e-4  # it is corrupted, not a copy
        scales.append(s)
        np.testing.assert_array_equal(provider.predict(frame).depth, out.depth)  # deterministic per frame
    assert np.ptp(scales) > 0.01  # a different scale per frame


@pytest.mark.parametrize("corruption", [OracleCorruption(), OracleCorruption.clean()])
def test_oracle_normals_unit_and_facing_camera(replica_small, corruption):
    frame = replica_small[0]
    n = OracleDepthNormal(corruption=corruption).predict(frame).normal
    assert n.shape == (frame.height, frame.width, 3) and n.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    assert ((n * view_rays(frame.intrinsics)).sum(-1) < 0).all()


def _error_statistics(provider, frames):
    """Mean over frames of (AbsRel of the depth after its per-frame least-squares scale and
    shift to GT, mean normal angle to the GT-depth normals in degrees, fitted scale)."""
    rel, ang, scales = [], [], []
    for f in frames:
        out = provider.predict(f)
        m = f.gt_depth > 0
        A = np.stack([out.depth[m], np.ones(m.sum())], 1).astype(np.float64)
        (s, t), *_ = np.linalg.lstsq(A, f.gt_depth[m].astype(np.float64), rcond=None)
        rel.append(np.mean(np.abs(A @ [s, t] - f.gt_depth[m]) / f.gt_depth[m]))
        n_gt = normals_from_depth(fill_invalid_nearest(f.gt_depth), f.intrinsics)
        ang.append(np.degrees(np.arccos(np.clip((n_gt * out.normal).sum(-1)[m], -1, 1))).mean())
        scales.append(s)
    return float(np.mean(rel)), float(np.mean(ang)), scales


@pytest.mark.parametrize("scene, seed", [("replica", 0), ("replica", 1), ("synthetic", 2)])
def test_realistic_oracle_has_a_monocular_networks_error_statistics(replica_dir, scene, seed):
    """On the Replica clip and the synthetic room at 320 px, for each seed: depth AbsRel after
    per-frame affine alignment in 0.08-0.11 and the normals' mean angular error in the ranges
    published for DPT/Omnidata-class networks (the docstring of `priors/oracle.py` cites them),
    the clean variant far below them."""
    from sources import open_source
    from sources.base import SourceOptions

    uri = f"replica:{replica_dir}" if scene == "replica" else "synthetic:room?frames=20"
    frames = list(open_source(uri, SourceOptions(max_side=320, stride=2)))
    rel, ang, scales = _error_statistics(make_depth_normal_provider("oracle", seed=seed), frames)
    assert 0.08 <= rel <= 0.11, rel
    assert 10.0 <= ang <= 20.0, ang
    assert max(scales) / min(scales) > 1.5  # the per-frame scale ambiguity stays
    rel_c, ang_c, _ = _error_statistics(make_depth_normal_provider("oracle:clean"), frames)
    assert rel_c < 0.02 and ang_c < 1.0, (rel_c, ang_c)


def test_oracle_names_say_which_variant_and_what_it_imitates():
    real, clean = make_depth_normal_provider("oracle"), make_depth_normal_provider("oracle:clean")
    assert (real.name, clean.name) == ("oracle", "oracle:clean")
    assert "monocular" in real.description and "debugging" in clean.description
    with pytest.raises(UserError):
        make_depth_normal_provider("oracle:dirty")


def _frame(index, depth, T, intr) -> Frame:
    rgb = np.zeros((intr.height, intr.width, 3), np.float32)
    return Frame(index=index, timestamp=0.0, rgb=rgb, intrinsics=intr, gt_pose=T, gt_depth=depth)


INTR = Intrinsics(fx=100.0, fy=100.0, cx=15.5, cy=11.5, width=32, height=24)


def test_oracle_flow_pure_translation_by_hand():
    depth = np.full((24, 32), 2.0, np.float32)
    depth[:, 16:] = 4.0
    T_dst = np.eye(4)
    T_dst[0, 3] = 0.1  # destination camera 10 cm to the right: points move left by fx * 0.1 / z
    fp = OracleFlow().flow(_frame(0, depth, np.eye(4), INTR), _frame(1, depth, T_dst, INTR))
    assert (fp.src_index, fp.dst_index) == (0, 1)
    np.testing.assert_allclose(fp.flow[5, 10], [-5.0, 0.0], atol=1e-4)  # z = 2 m
    np.testing.assert_allclose(fp.flow[7, 20], [-2.5, 0.0], atol=1e-4)  # z = 4 m
    # Out of image: u - 5 < -0.5 for u <= 4 (z = 2 m side).
    assert not fp.valid[:, :5].any() and fp.valid[:, 5:16].all()


def test_oracle_flow_forward_motion_by_hand():
    depth = np.full((24, 32), 2.0, np.float32)
    T_dst = np.eye(4)
    T_dst[2, 3] = 0.5  # move 0.5 m forward: z 2 -> 1.5
    flow, valid = flow_from_depth_pose(depth, np.eye(4), INTR, T_dst, INTR)
    u, v = 25, 3
    x, y = (u - INTR.cx) / INTR.fx * 2.0, (v - INTR.cy) / INTR.fy * 2.0
    expected = [INTR.fx * x / 1.5 + INTR.cx - u, INTR.fy * y / 1.5 + INTR.cy - v]
    np.testing.assert_allclose(flow[v, u], expected, atol=1e-4)
    assert valid[v, u]


def test_oracle_flow_marks_occlusion():
    depth = np.full((24, 32), 2.0, np.float32)
    dst_depth = depth.copy()
    dst_depth[8:16, 8:16] = 1.0  # something closer in front, in the destination view only
    flow, valid = flow_from_depth_pose(depth, np.eye(4), INTR, np.eye(4), INTR, dst_depth)
    np.testing.assert_allclose(flow, 0.0, atol=1e-5)
    assert not valid[8:16, 8:16].any() and valid[:8].all() and valid[16:].all()


def test_oracle_flow_matches_real_images(replica_small):
    """Warping frame 1 by the oracle flow 0 -> 1 reproduces frame 0 much better than no flow."""
    f0, f1 = replica_small[:2]
    fp = OracleFlow().flow(f0, f1)
    h, w = f0.height, f0.width
    x = (np.arange(w)[None, :] + fp.flow[..., 0]).astype(np.float32)
    y = (np.arange(h)[:, None] + fp.flow[..., 1]).astype(np.float32)
    warped = cv2.remap(f1.rgb, x, y, cv2.INTER_LINEAR)
    m = fp.valid
    err_flow = np.abs(warped - f0.rgb)[m].mean()
    err_none = np.abs(f1.rgb - f0.rgb)[m].mean()
    assert m.mean() > 0.8 and err_flow < 0.5 * err_none, (err_flow, err_none)


def test_oracle_without_ground_truth_is_a_one_line_user_error(replica_small):
    bare = replica_small[0].without_ground_truth()
    for call in (lambda: OracleDepthNormal().predict(bare), lambda: OracleFlow().flow(bare, bare)):
        with pytest.raises(UserError) as e:
            call()
        msg = str(e.value)
        assert "oracle" in msg and "ground truth" in msg and "\n" not in msg


def test_fill_invalid_nearest():
    d = np.array([[0.0, 1.0, 0.0, 0.0, 5.0]], np.float32)
    np.testing.assert_array_equal(fill_invalid_nearest(d), [[1.0, 1.0, 1.0, 5.0, 5.0]])
    with pytest.raises(UserError):
        fill_invalid_nearest(np.zeros((2, 2), np.float32))


def test_the_oracle_seed_is_the_configs_and_changes_the_corruption(replica_small):
    from nicer_stream.runtime.frame_priors import make_engine

    frame = replica_small[0]
    a, b = (make_engine("oracle", "dis", "cpu", seed=s).depth_normal for s in (0, 1))
    assert (a.seed, b.seed) == (0, 1)
    assert not np.allclose(a.predict(frame).depth, b.predict(frame).depth)
    np.testing.assert_array_equal(a.predict(frame).depth, make_engine("oracle", "dis", "cpu", seed=0).depth_normal.predict(frame).depth)


def _log_error(provider, frame):
    """log(prior / GT) after the frame's least-squares affine alignment of the prior to GT."""
    out = provider.predict(frame)
    gt = fill_invalid_nearest(frame.gt_depth).astype(np.float64)
    A = np.stack([out.depth.ravel(), np.ones(gt.size)], 1).astype(np.float64)
    (s, t), *_ = np.linalg.lstsq(A, gt.ravel(), rcond=None)
    return np.log(np.maximum(A @ [s, t], 1e-3) / gt.ravel()).reshape(gt.shape)


def test_oracle_depth_errors_are_consistent_across_views(replica_small):
    """A place seen by two frames has about the same depth error in both (a network errs the
    same way on the same surface): the errors at the pixels that see one point correlate."""
    from nicer_stream.priors.oracle import flow_from_depth_pose

    provider = make_depth_normal_provider("oracle", seed=4)
    f0, f1 = replica_small[0], replica_small[1]
    flow, valid = flow_from_depth_pose(f0.gt_depth, f0.gt_pose, f0.intrinsics, f1.gt_pose, f1.intrinsics, f1.gt_depth)
    e0, e1 = _log_error(provider, f0), _log_error(provider, f1)
    h, w = e0.shape
    v, u = np.nonzero(valid)
    u1 = np.clip(np.round(u + flow[v, u, 0]).astype(int), 0, w - 1)
    v1 = np.clip(np.round(v + flow[v, u, 1]).astype(int), 0, h - 1)
    assert len(u) > 0.3 * h * w
    corr = np.corrcoef(e0[v, u], e1[v1, u1])[0, 1]
    assert corr > 0.6, corr
