"""evaluate_output_dir and `nicer-stream eval` on hand-made output directories."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from typer.testing import CliRunner

from nicer_stream.cli.main import app
from nicer_stream.errors import UserError
from nicer_stream.eval.evaluate import evaluate_output_dir
from nicer_stream.eval.trajectory import Sim3
from tests.nicer_stream.geometry.rotations import so3_exp
from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import write_tum
from nicer_stream.types import Frame, Intrinsics
from sources import open_source
from sources.base import FrameSource, SourceOptions
from tests.nicer_stream.eval.sim3_poses import apply_poses

SIDE = 160  # renders and evaluation at this size keep the tests fast


def replica(replica_dir: Path, **kw):
    return open_source(f"replica:{replica_dir}", SourceOptions(**kw))


@pytest.fixture(scope="module")
def frames10(replica_dir) -> list[Frame]:
    return list(replica(replica_dir, max_side=SIDE, max_frames=10))


def translated(t) -> np.ndarray:
    """(4, 4) pure translation."""
    T = np.eye(4)
    T[:3, 3] = t
    return T


def gt_traj(frames) -> tuple[np.ndarray, np.ndarray]:
    return np.array([f.timestamp for f in frames]), np.stack([f.gt_pose for f in frames])


def checker(shape) -> np.ndarray:
    """(H, W, 1) +-1 checkerboard."""
    return np.where(np.indices(shape[:2]).sum(0) % 2 == 0, 1.0, -1.0)[..., None]


def write_render(out: Path, f: Frame, depth_scale: float) -> None:
    """A render that differs from the GT image by +-0.1 (20 dB) and whose depth is GT / scale."""
    (out / od.RENDERS_DIR).mkdir(exist_ok=True)
    sign = np.where(f.rgb < 0.5, 1.0, -1.0) * checker(f.rgb.shape)
    rgb = (f.rgb + 0.1 * sign).astype(np.float32)
    depth = np.where(f.gt_depth > 0, f.gt_depth / depth_scale, 123.0).astype(np.float32)  # junk off GT-valid pixels
    np.savez(out / od.RENDERS_DIR / od.render_name(f.index), rgb=rgb, depth=depth,
             normal=np.zeros_like(rgb), frame_index=f.index)


def depth_mesh(f: Frame) -> trimesh.Trimesh:
    """Grid triangulation of a frame's GT depth in the GT world (no faces across depth jumps)."""
    H, W = f.gt_depth.shape
    v, u = np.mgrid[0:H, 0:W]
    K = f.intrinsics
    p = np.stack([(u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones_like(u, float)], -1) * f.gt_depth[..., None]
    p = p.reshape(-1, 3) @ f.gt_pose[:3, :3].T + f.gt_pose[:3, 3]
    i = (v[:-1, :-1] * W + u[:-1, :-1]).reshape(-1)
    faces = np.concatenate([np.stack([i, i + 1, i + W], 1), np.stack([i + 1, i + W + 1, i + W], 1)])
    d = f.gt_depth.reshape(-1)[faces]
    ok = (d.min(1) > 0) & (d.max(1) - d.min(1) < 0.05 * d.min(1))
    return trimesh.Trimesh(p, faces[ok], process=False)


def test_gt_trajectory_gives_zero_and_nulls(tmp_path, replica_dir, frames10):
    write_tum(tmp_path / od.TRAJECTORY_FILE, *gt_traj(frames10))
    rep = evaluate_output_dir(tmp_path, replica(replica_dir, max_side=SIDE, max_frames=10))
    assert rep.ate_rmse_m < 1e-6 and rep.ate_se3_rmse_m < 1e-6
    assert rep.rpe_trans_m < 1e-6 and rep.rpe_rot_deg < 1e-4
    assert rep.sim3_scale == pytest.approx(1.0, abs=1e-5)
    assert rep.psnr_db is None and rep.depth_l1_m is None and rep.mesh.acc_m is None
    assert rep.evaluated_views.frame_indices == []


def test_perturbed_trajectory_matches_closed_form(tmp_path, replica_dir, frames10):
    t, gt = gt_traj(frames10)
    y = gt[:, :3, 3]
    # Offsets c_i * n on frames 2..6 with sum c_i = 0 and sum c_i y_i = 0: then the
    # cross-covariance stays symmetric, so the optimal rotation is I and translation 0.
    k = [2, 3, 4, 5, 6]
    A = np.vstack([np.ones(5), y[k].T])  # (4, 5)
    c = np.linalg.svd(A)[2][-1]
    c *= 0.05 / np.abs(c).max()
    e = np.zeros_like(y)
    e[k] = c[:, None] * np.array([0.0, 0.6, 0.8])
    est = gt.copy()
    est[:, :3, 3] += e
    write_tum(tmp_path / od.TRAJECTORY_FILE, t, est)
    rep = evaluate_output_dir(tmp_path, replica(replica_dir, max_side=SIDE, max_frames=10))
    e2 = (e**2).sum(1).mean()
    var_y = ((y - y.mean(0)) ** 2).sum(1).mean()
    s = var_y / (var_y + e2)  # Sim(3) shrinks the noisy estimate towards its centroid
    assert rep.ate_se3_rmse_m == pytest.approx(np.sqrt(e2), rel=1e-5)
    assert rep.sim3_scale == pytest.approx(s, rel=1e-5)
    assert rep.ate_rmse_m == pytest.approx(np.sqrt((1 - s) ** 2 * var_y + s**2 * e2), rel=1e-5)
    assert rep.rpe_rot_deg < 1e-4 and rep.rpe_trans_m > 0.01


def test_sim3_world_renders_and_mesh(tmp_path, replica_dir, frames10):
    t, gt = gt_traj(frames10)
    k = 2.0  # the estimate's world is rotated, shifted and twice as large as the GT world
    G = Sim3(so3_exp(torch.tensor([0.3, -1.0, 0.5], dtype=torch.float64)).numpy(), np.array([1.0, -2.0, 0.5]), k)
    write_tum(tmp_path / od.TRAJECTORY_FILE, t, apply_poses(G, gt))
    for f in frames10[::4]:
        write_render(tmp_path, f, depth_scale=1 / k)
    m = depth_mesh(frames10[0])
    M = translated(G.t)
    M[:3, :3] = k * G.R
    m.apply_transform(M)  # GT world -> estimate world
    m.export(tmp_path / od.MESH_FILE)
    od.write_summary(tmp_path, od.Summary(10, "fast", "cpu", ["oracle"], 1.0, od.StageSeconds(), 0.1, 100.0, {}, False))
    rep = evaluate_output_dir(tmp_path, replica(replica_dir, max_side=SIDE, max_frames=10), mesh_samples=20_000)
    assert rep.ate_rmse_m < 1e-6 and rep.sim3_scale == pytest.approx(1 / k, rel=1e-6)
    assert rep.ate_se3_rmse_m > 0.01  # SE(3) cannot undo the scale
    assert rep.rpe_trans_m < 1e-6
    assert rep.psnr_db == pytest.approx(20.0, abs=1e-3) and 0 < rep.ssim < 1
    assert rep.depth_l1_pose_aligned_m < 1e-5  # junk depth outside GT-valid pixels ignored, scale applied
    assert rep.depth_l1_m < 5e-3  # ICP onto 2 cm voxel averages of GT depth: scale within ~0.15%
    assert rep.evaluated_views.frame_indices == [0, 4, 8]
    assert (rep.evaluated_views.width, rep.evaluated_views.height) == frames10[0].rgb.shape[1::-1]
    assert rep.priors == ["oracle"]
    mr = rep.mesh
    assert mr.reference == "gt_depth_points"
    assert mr.acc_m < 0.02  # the mesh lies on GT depth once the Sim(3) is undone
    assert 0 < mr.comp_ratio <= 1 and mr.normal_consistency > 0.8


class PlaneSource(FrameSource):
    """Two cameras looking along +z at the plane z = 2; its GT mesh is a 20 m square."""

    intr = Intrinsics(50.0, 50.0, 49.5, 39.5, 100, 80)

    def _frames(self):
        for i, x in enumerate([0.0, 0.1]):
            T = np.eye(4)
            T[0, 3] = x
            rgb = np.full((80, 100, 3), 0.5, np.float32)
            yield Frame(i, i * 0.1, rgb, self.intr, T, np.full((80, 100), 2.0, np.float32))

    def gt_mesh(self) -> trimesh.Trimesh:
        return trimesh.creation.box([20.0, 20.0, 1e-3], translated([0.0, 0.0, 2.0]))


def test_gt_mesh_is_culled_to_observed(tmp_path):
    src = PlaneSource()
    write_tum(tmp_path / od.TRAJECTORY_FILE, *gt_traj(list(src)))
    patch = trimesh.creation.box([4.4, 3.6, 1e-3], translated([0.05, 0.0, 2.0]))
    patch.export(tmp_path / od.MESH_FILE)
    rep = evaluate_output_dir(tmp_path, src, mesh_samples=20_000)
    assert rep.mesh.reference == "gt_mesh"
    # Only the seen ~4 x 3.2 m of the 20 x 20 m GT plane count: completion is full.
    assert rep.mesh.comp_ratio > 0.99 and rep.mesh.comp_m < 0.02
    assert rep.mesh.normal_consistency > 0.9


def test_missing_inputs_give_nulls_and_bad_files_one_line_errors(tmp_path, replica_dir):
    src = replica(replica_dir, max_side=SIDE, max_frames=2)
    rep = evaluate_output_dir(tmp_path, src)
    assert rep == od.EvalReport()
    with pytest.raises(UserError, match="not found"):
        evaluate_output_dir(tmp_path / "nope", src)
    (tmp_path / od.TRAJECTORY_FILE).write_text("0 1 2 3\n")
    with pytest.raises(UserError) as e:
        evaluate_output_dir(tmp_path, src)
    assert "\n" not in str(e.value)


def test_cli_eval_writes_eval_json(tmp_path, replica_dir, frames10):
    write_tum(tmp_path / od.TRAJECTORY_FILE, *gt_traj(frames10))
    write_render(tmp_path, frames10[3], depth_scale=1.0)
    # Full-size source: eval resizes it to the render's size.
    res = CliRunner().invoke(app, ["eval", str(tmp_path), "--source", f"replica:{replica_dir}", "--max-frames", "10"])
    assert res.exit_code == 0, res.output
    assert "ATE RMSE" in res.output
    rep = od.read_eval(tmp_path)
    assert rep.ate_rmse_m < 1e-6 and rep.depth_l1_m < 1e-6
    assert rep.psnr_db == pytest.approx(20.0, abs=1e-3)
    assert rep.evaluated_views.frame_indices == [3]


def test_cli_missing_outdir_is_one_line_exit_2(tmp_path, replica_dir):
    res = CliRunner().invoke(app, ["eval", str(tmp_path / "missing"), "--source", f"replica:{replica_dir}"])
    assert res.exit_code == 2
    msg = res.stderr if hasattr(res, "stderr") else res.output
    assert msg.strip().startswith("error:") and len(msg.strip().splitlines()) == 1


def test_cli_without_source_or_summary_is_one_line_exit_2(tmp_path):
    res = CliRunner().invoke(app, ["eval", str(tmp_path)])
    assert res.exit_code == 2
    msg = res.stderr if hasattr(res, "stderr") else res.output
    assert "--source" in msg and len(msg.strip().splitlines()) == 1


def test_scene_registered_when_the_map_scale_differs_from_the_trajectory(tmp_path, replica_dir, frames10):
    """A map 3% larger (about camera 0) than its exact trajectory implies: the paper's ICP
    alignment recovers its scale; the trajectory-only numbers are reported next to it."""
    write_tum(tmp_path / od.TRAJECTORY_FILE, *gt_traj(frames10))
    f0 = frames10[0]
    write_render(tmp_path, f0, depth_scale=1 / 1.03)  # frame 0 sees the scene 3% deeper
    m = depth_mesh(f0)
    c0 = f0.gt_pose[:3, 3]
    m.vertices = c0 + 1.03 * (np.asarray(m.vertices) - c0)
    m.export(tmp_path / od.MESH_FILE)
    rep = evaluate_output_dir(tmp_path, replica(replica_dir, max_side=SIDE, max_frames=10), mesh_samples=20_000)
    assert rep.sim3_scale == pytest.approx(1.0, abs=1e-6) and rep.scene_alignment == "icp"
    assert rep.scene_scale == pytest.approx(1 / 1.03, rel=5e-3)
    # 1.1 cm is this set-up's floor: the exact alignment gives the same (depth mesh vs voxelised GT).
    assert rep.mesh.acc_m < 0.012 and rep.mesh_pose_aligned.acc_m > 0.05
    assert rep.mesh.comp_ratio > 0.9 > 0.2 > rep.mesh_pose_aligned.comp_ratio
    assert rep.depth_l1_m < 5e-3 and rep.depth_l1_pose_aligned_m > 0.05
