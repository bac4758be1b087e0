"""The frames that keep the frontend's pose (`tracking.refine = 'keyframes'`) moved with the
corrections the map made to the keyframes around them.

A keyframe's pose is the frontend's refined against the map and then adjusted by the mapping's
bundle adjustment; the frames between keyframes hold the frontend's pose, in the frontend's own
slowly drifting frame. Reported as they are, the trajectory jumps at every keyframe (on the demo
room up to 1.5 degrees between a keyframe and its neighbours). Each anchor's correction is the
world-frame change `dT = T_now @ inv(T_frontend)`; a frame between two anchors moves by the
linear blend of their corrections' twists (by position in the input order), beyond the last
anchor by its correction.
"""
from __future__ import annotations

import bisect

import torch

from nicer_stream.geometry.se3 import invert, se3_exp, se3_log


def spread_corrections(order: list[int], poses: dict[int, torch.Tensor], frontend: dict[int, torch.Tensor],
                       anchors: set[int], followers: set[int]) -> dict[int, torch.Tensor]:
    """T_world_cam (4, 4) of every frame in `order` (frame indices, input order). `poses`: each
    frame's pose now; `frontend`: the frontend's pose of the frames it placed; `anchors`: frames
    whose pose the map decided (their correction `poses[k] @ inv(frontend[k])`, the identity
    without a frontend pose: the start's frames); `followers`: frames holding the frontend's pose,
    moved by the blended corrections. Other frames, and all frames when there is no anchor, keep
    their pose."""
    pos = {k: i for i, k in enumerate(order)}
    marks = []
    for k in sorted(anchors, key=pos.__getitem__):
        T_f = frontend.get(k)
        xi = torch.zeros(6, dtype=torch.float64, device=poses[k].device) if T_f is None else se3_log(poses[k].double() @ invert(T_f.double()))
        marks.append((pos[k], xi))
    at = [p for p, _ in marks]
    out = {}
    for i, k in enumerate(order):
        if k not in followers or k in anchors or not marks:
            out[k] = poses[k]
            continue
        j = bisect.bisect_left(at, i)  # marks[j - 1] before frame i, marks[j] after it
        if 0 < j < len(marks):
            (p0, x0), (p1, x1) = marks[j - 1], marks[j]
            xi = x0 + (x1 - x0) * ((i - p0) / (p1 - p0))
        else:
            xi = marks[min(j, len(marks) - 1)][1]
        out[k] = (se3_exp(xi) @ poses[k].double()).to(poses[k].dtype)
    return out
