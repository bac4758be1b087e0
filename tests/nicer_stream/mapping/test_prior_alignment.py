"""Metric alignment of a relative depth prior by flow triangulation with known poses."""
import torch

from nicer_stream.geometry.camera import pixel_grid, project, unproject
from nicer_stream.geometry.se3 import invert, se3_exp, transform_points
from nicer_stream.mapping.prior_alignment import robust_affine_fit, triangulate_depth
from nicer_stream.types import Intrinsics

INTR = Intrinsics(80.0, 80.0, 31.5, 23.5, 64, 48)


def _scene():
    T_src = se3_exp(torch.tensor([0.1, -0.2, 0.3, 0.05, -0.1, 0.02], dtype=torch.float64))
    T_dst = T_src @ se3_exp(torch.tensor([0.25, 0.05, 0.02, 0.01, 0.04, -0.02], dtype=torch.float64))
    uv = pixel_grid(INTR).double()
    depth = 2.0 + 0.5 * torch.sin(uv[:, 0] / 10) + 0.01 * uv[:, 1]
    p_world = transform_points(T_src, unproject(uv, depth, INTR))
    uv_dst, _ = project(transform_points(invert(T_dst), p_world), INTR)
    return uv, uv_dst, depth, T_src, T_dst


def test_triangulation_recovers_depth_exactly():
    uv, uv_dst, depth, T_src, T_dst = _scene()
    z, ok = triangulate_depth(uv, uv_dst, INTR, INTR, T_src, T_dst)
    assert ok.float().mean() > 0.95
    assert torch.allclose(z[ok], depth[ok], rtol=1e-6)


def test_no_baseline_means_no_valid_depth():
    uv, _, _, T_src, _ = _scene()
    z, ok = triangulate_depth(uv, uv.clone(), INTR, INTR, T_src, T_src)
    assert not ok.any()


def test_affine_fit_recovers_scale_and_shift_despite_outliers():
    g = torch.Generator().manual_seed(0)
    depth = torch.rand(500, generator=g, dtype=torch.float64) * 3 + 1
    prior = 0.7 * depth + 0.2
    prior[:50] += 5.0  # 10% gross outliers
    w, q = robust_affine_fit(prior, depth)
    assert abs(w - 0.7) < 1e-6 and abs(q - 0.2) < 1e-6
    assert robust_affine_fit(prior[:10], depth[:10]) is None
