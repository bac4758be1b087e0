import math
from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from nicer_stream.geometry.camera import pixel_grid
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.losses.brightness import apply_brightness
from nicer_stream.losses.warping import bilinear_sample, warp_pixels, warping_loss
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=100.0, fy=110.0, cx=31.5, cy=23.5, width=64, height=48)
DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data"


def _pose(xi):
    return se3_exp(torch.tensor(xi, dtype=torch.float64))


def test_identical_poses_is_identity():
    uv = pixel_grid(INTR, dtype=torch.float64)
    depth = 0.5 + torch.rand(len(uv), dtype=torch.float64)
    T = _pose([0.3, -0.2, 1.0, 0.1, 0.4, -0.3])
    uv_dst, z, valid = warp_pixels(uv, depth, INTR, T, INTR, T)
    assert torch.allclose(uv_dst, uv, atol=1e-9) and torch.allclose(z, depth) and valid.all()


def test_translation_gives_closed_form_shift_on_fronto_parallel_plane():
    intr_dst = Intrinsics(fx=80.0, fy=90.0, cx=30.0, cy=20.0, width=64, height=48)
    uv = pixel_grid(INTR, dtype=torch.float64)
    Z, (tx, ty, tz) = 2.0, (0.1, -0.05, 0.2)
    T_src = torch.eye(4, dtype=torch.float64)
    T_dst = _pose([tx, ty, tz, 0.0, 0.0, 0.0])
    uv_dst, z, valid = warp_pixels(uv, torch.full((len(uv),), Z, dtype=torch.float64), INTR, T_src, intr_dst, T_dst)
    X = (uv[:, 0] - INTR.cx) / INTR.fx * Z
    Y = (uv[:, 1] - INTR.cy) / INTR.fy * Z
    u_ref = intr_dst.fx * (X - tx) / (Z - tz) + intr_dst.cx
    v_ref = intr_dst.fy * (Y - ty) / (Z - tz) + intr_dst.cy
    assert torch.allclose(uv_dst, torch.stack([u_ref, v_ref], -1), atol=1e-9)
    assert torch.allclose(z, torch.full_like(z, Z - tz))
    inside = (u_ref >= -0.5) & (u_ref <= 63.5) & (v_ref >= -0.5) & (v_ref <= 47.5)
    assert torch.equal(valid, inside) and not valid.all() and valid.any()


def test_points_behind_destination_are_invalid():
    uv = torch.tensor([[31.5, 23.5]], dtype=torch.float64)
    T_dst = _pose([0.0, 0.0, 3.0, 0.0, 0.0, 0.0])  # 3 m ahead: the 1 m point is behind it
    _, z, valid = warp_pixels(uv, torch.tensor([1.0], dtype=torch.float64), INTR, torch.eye(4, dtype=torch.float64), INTR, T_dst)
    assert z.item() < 0 and not valid.item()


def test_gradcheck_wrt_depth_and_pose_twists():
    uv = torch.tensor([[10.0, 5.0], [40.0, 30.0], [20.5, 44.0]], dtype=torch.float64)
    T0s, T0d = _pose([0.1, 0.0, 0.0, 0.0, 0.1, 0.0]), _pose([0.0, 0.2, -0.1, 0.05, 0.0, 0.1])

    def f(depth, xi_s, xi_d):
        uv_dst, z, _ = warp_pixels(uv, depth, INTR, T0s @ se3_exp(xi_s), INTR, T0d @ se3_exp(xi_d))
        return uv_dst, z

    args = (
        torch.tensor([1.0, 2.0, 3.0], dtype=torch.float64, requires_grad=True),
        torch.zeros(6, dtype=torch.float64, requires_grad=True),
        torch.zeros(6, dtype=torch.float64, requires_grad=True),
    )
    assert torch.autograd.gradcheck(f, args)
    uv_dst, _ = f(*args)
    grads = torch.autograd.grad(uv_dst.sum(), args)
    assert all(torch.isfinite(g).all() and g.abs().sum() > 0 for g in grads)


def test_bilinear_exact_at_centres_and_linear_between():
    g = torch.Generator().manual_seed(4)
    img = torch.rand(5, 7, 3, generator=g, dtype=torch.float64)
    v, u = torch.meshgrid(torch.arange(5), torch.arange(7), indexing="ij")
    uv = torch.stack([u.reshape(-1), v.reshape(-1)], -1).double()
    assert torch.equal(bilinear_sample(img, uv), img.reshape(-1, 3))
    a, b = 0.3, 0.8
    ref = (1 - b) * ((1 - a) * img[2, 4] + a * img[2, 5]) + b * ((1 - a) * img[3, 4] + a * img[3, 5])
    assert torch.allclose(bilinear_sample(img, torch.tensor([[4 + a, 2 + b]], dtype=torch.float64))[0], ref)
    # Independent reference: grid_sample with align_corners=True is the pixel-centre convention.
    uv_r = torch.rand(100, 2, generator=g, dtype=torch.float64) * torch.tensor([6.0, 4.0])
    grid = (2 * uv_r / torch.tensor([6.0, 4.0]) - 1)[None, None]
    ref = F.grid_sample(img.permute(2, 0, 1)[None], grid, align_corners=True)[0, :, 0].T
    assert torch.allclose(bilinear_sample(img, uv_r), ref)


def test_bilinear_clamps_outside_and_has_uv_gradient():
    img = torch.arange(12.0).reshape(3, 4, 1)
    out = bilinear_sample(img, torch.tensor([[-0.5, -0.5], [100.0, 1.0]]))
    assert torch.equal(out[:, 0], torch.tensor([0.0, 7.0]))
    uv = torch.tensor([[1.25, 1.5]], requires_grad=True)
    bilinear_sample(img, uv).sum().backward()
    assert torch.allclose(uv.grad, torch.tensor([[1.0, 4.0]]))  # d/du = 1, d/dv = W


def test_warping_loss_zero_for_consistent_warp_and_masks_invalid():
    g = torch.Generator().manual_seed(5)
    img = torch.rand(48, 64, 3, generator=g)
    uv = torch.rand(30, 2, generator=g) * torch.tensor([63.0, 47.0])
    rgb = bilinear_sample(img, uv)
    valid = torch.ones(30, dtype=torch.bool)
    assert warping_loss(rgb, [img, img], [uv, uv], [valid, valid]).item() < 1e-6
    wrong = rgb.clone()
    wrong[0] += 1.0  # |.|_1 = 3 on one of 60 pairs
    assert abs(warping_loss(wrong, [img, img], [uv, uv], [valid, valid]).item() - 6 / 60) < 1e-5
    valid[0] = False
    assert warping_loss(wrong, [img, img], [uv, uv], [valid, valid]).item() < 1e-6
    with pytest.raises(ValueError):
        warping_loss(rgb, [img], [uv, uv], [valid])


def _replica(i):
    import cv2

    root = DATA / "replica_room0_20f"
    rgb = cv2.imread(str(root / "results" / f"frame{i:06d}.jpg"))[..., ::-1].astype(np.float32) / 255
    depth = cv2.imread(str(root / "results" / f"depth{i:06d}.png"), cv2.IMREAD_UNCHANGED) / 6553.5
    T = np.loadtxt(root / "traj.txt")[i].reshape(4, 4)
    return torch.from_numpy(rgb.copy()), torch.from_numpy(depth), torch.from_numpy(T)


@pytest.mark.skipif(not (DATA / "replica_room0_20f").exists(), reason="shared Replica clip not present")
def test_real_replica_gt_depth_and_poses_minimise_warping_loss():
    intr = Intrinsics(fx=600.0, fy=600.0, cx=599.5, cy=339.5, width=1200, height=680)
    rgb0, depth0, T0 = _replica(0)
    rgb1, _, T1 = _replica(19)
    g = torch.Generator().manual_seed(6)
    uv = torch.stack([torch.randint(0, 1200, (3000,), generator=g), torch.randint(0, 680, (3000,), generator=g)], -1)
    d = depth0[uv[:, 1], uv[:, 0]]
    rgb_src = rgb0[uv[:, 1], uv[:, 0]]

    def loss(T_dst):
        uv_dst, _, valid = warp_pixels(uv.double(), d, intr, T0, intr, T_dst)
        return warping_loss(rgb_src, [rgb1], [uv_dst], [valid]).item()

    true = loss(T1)
    assert true < 0.05  # about 3 colour levels per channel: JPEG noise, occlusions
    assert loss(T0) > 2.5 * true  # ignoring the 24 cm of motion
    for xi in ([0.05, 0, 0, 0, 0, 0], [0, 0.05, 0, 0, 0, 0], [0, 0, 0.05, 0, 0, 0], [0, 0, 0, 0.02, 0, 0], [0, 0, 0, 0, 0.02, 0]):
        assert loss(T1 @ _pose(xi)) > 2.5 * true  # 5 cm or ~1 degree off in the camera frame


def test_warping_loss_compares_in_the_source_exposure_with_brightness():
    """The partner saw the scene with gain 1.4 and bias -0.1, the source with gain 0.9 and bias
    0.02: with both frames' brightness the warp is consistent again; without it, it is not."""
    g = torch.Generator().manual_seed(6)
    scene = torch.rand(48, 64, 3, generator=g) * 0.6 + 0.1
    ab_src, ab_dst = torch.tensor([math.log(0.9), 0.02]), torch.tensor([math.log(1.4), -0.1])
    uv = torch.rand(40, 2, generator=g) * torch.tensor([63.0, 47.0])
    src = apply_brightness(bilinear_sample(scene, uv), ab_src)
    dst = apply_brightness(scene, ab_dst)
    valid = torch.ones(40, dtype=torch.bool)
    assert warping_loss(src, [dst], [uv], [valid]).item() > 0.1
    assert warping_loss(src, [dst], [uv], [valid], 0.0, ab_src, [ab_dst]).item() < 1e-5
    x = ab_dst.clone().requires_grad_()
    (gx,) = torch.autograd.grad(warping_loss(src, [dst], [uv], [valid], 0.05, ab_src, [x + 0.1]), [x])
    assert torch.isfinite(gx).all() and gx.abs().sum() > 0


def test_warping_loss_with_huber_keeps_l1_slope_for_large_errors():
    g = torch.Generator().manual_seed(7)
    img = torch.rand(48, 64, 3, generator=g)
    uv = torch.rand(10, 2, generator=g) * torch.tensor([63.0, 47.0])
    wrong = bilinear_sample(img, uv) + 1.0
    valid = torch.ones(10, dtype=torch.bool)
    assert abs(warping_loss(wrong, [img], [uv], [valid], 0.1).item() - (3.0 - 3 * 0.05)) < 1e-5
