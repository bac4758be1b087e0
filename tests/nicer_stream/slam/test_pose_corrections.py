"""The frames holding the frontend's pose follow the map's corrections of the keyframes."""
import torch

from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.slam.pose_corrections import spread_corrections


def _pose(*xi: float) -> torch.Tensor:
    return se3_exp(torch.tensor(xi, dtype=torch.float64))


def test_a_translation_correction_is_blended_by_position_and_held_beyond_the_last_anchor():
    order = [0, 1, 2, 3, 4, 5, 6]
    poses = {k: _pose(0.1 * k, 0, 0, 0, 0.02 * k, 0) for k in order}
    frontend = {k: poses[k].clone() for k in order if k}
    poses[4] = _pose(0, 0, 0.08, 0, 0, 0) @ poses[4]  # the map moved keyframe 4 by 8 cm along z
    out = spread_corrections(order, poses, frontend, anchors={0, 4}, followers={1, 2, 3, 5})
    for k in (1, 2, 3):  # frame 0 (the start: no frontend pose) has no correction
        torch.testing.assert_close(out[k], _pose(0, 0, 0.02 * k, 0, 0, 0) @ poses[k])
    torch.testing.assert_close(out[5], _pose(0, 0, 0.08, 0, 0, 0) @ poses[5])
    for k in (0, 4, 6):  # anchors, and a frame that is not a follower, keep their pose
        assert torch.equal(out[k], poses[k])


def test_a_frontend_drift_linear_in_its_twist_is_removed_exactly():
    order = list(range(11))
    gt = {k: _pose(0.03 * k, 0.01 * k, 0.002 * k * k, 0.01 * k, 0.02 * k, 0) for k in order}
    drift = torch.tensor([0.004, -0.002, 0.003, 0.001, -0.002, 0.0015], dtype=torch.float64)
    frontend = {k: se3_exp(k * drift) @ gt[k] for k in order}  # the frontend's world drifts away
    keyframes = {0, 5, 10}
    poses = {k: gt[k] if k in keyframes else frontend[k] for k in order}  # keyframes refined to the map
    out = spread_corrections(order, poses, frontend, anchors=keyframes, followers=set(order) - keyframes)
    for k in order:
        torch.testing.assert_close(out[k], gt[k], atol=1e-9, rtol=0)
    before = max(float((poses[k][:3, 3] - gt[k][:3, 3]).norm()) for k in order)
    assert before > 0.01  # the check means something: the drift was centimetres


def test_without_anchors_nothing_moves():
    order = [3, 4, 5]
    poses = {k: _pose(0.1 * k, 0, 0, 0, 0, 0) for k in order}
    out = spread_corrections(order, poses, {k: _pose(0, 0, 0, 0, 0, 0) for k in order}, set(), set(order))
    assert all(torch.equal(out[k], poses[k]) for k in order)
