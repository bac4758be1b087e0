"""Disagreements between the frontend and the map are settled by evidence: the photometric
loss at each pose, then the agreement with the constant-velocity motion; neither good: lost."""
import torch

from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.slam.disagreement import DisagreementStreaks, judge_disagreement


def T(x: float) -> torch.Tensor:
    return se3_exp(torch.tensor([x, 0.0, 0.0, 0.0, 0.0, 0.0]))


RECENT = [0.10, 0.11, 0.09]


def test_the_lower_loss_wins_either_way():
    assert judge_disagreement(0.05, 0.10, T(0.1), T(0.0), T(0.0), RECENT, 3.0, 0.85).keep == "map"
    assert judge_disagreement(0.10, 0.05, T(0.1), T(0.0), T(0.1), RECENT, 3.0, 0.85).keep == "frontend"


def test_alike_losses_go_to_the_pose_nearer_the_motion():
    assert judge_disagreement(0.10, 0.105, T(0.1), T(0.0), T(0.09), RECENT, 3.0, 0.85).keep == "map"
    v = judge_disagreement(0.10, 0.105, T(0.1), T(0.0), T(0.01), RECENT, 3.0, 0.85)
    assert v.keep == "frontend" and "nearer the motion" in v.why


def test_a_lower_loss_does_not_win_for_a_pose_that_misplaces_the_landmarks():
    # The refined pose minimised the loss against the map: it must still place the tracks.
    v = judge_disagreement(0.05, 0.10, T(0.1), T(0.0), T(0.1), RECENT, 3.0, 0.85, reproj_map_px=9.0, reproj_limit_px=4.0)
    assert v.keep == "frontend" and "misplaces the frame's landmarks" in v.why
    assert judge_disagreement(0.05, 0.10, T(0.1), T(0.0), T(0.1), RECENT, 3.0, 0.85, reproj_map_px=3.0,
                              reproj_limit_px=4.0).keep == "map"


def test_a_frame_neither_pose_explains_is_lost():
    v = judge_disagreement(0.5, 0.6, T(0.1), T(0.0), T(0.0), RECENT, 3.0, 0.85)
    assert v.keep == "lost" and "neither pose" in v.why
    assert judge_disagreement(float("nan"), float("inf"), T(0.1), T(0.0), T(0.0), [], 3.0, 0.85).keep == "lost"


def test_streaks_are_reported_once_when_they_reach_the_bound_and_grow():
    s = DisagreementStreaks(report_after=3)
    flags = [True, True, False, True, True, True, True, False, True]
    fired = [s.observe(i, d) for i, d in enumerate(flags)]
    assert fired == [False, False, False, False, False, True, False, False, False]
    assert s.streaks == [(3, 4)]
