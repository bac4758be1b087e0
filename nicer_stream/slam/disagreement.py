"""Which pose a frame keeps when the classical frontend and the refinement against the map
disagree: decided by evidence, not by rank. Both poses are scored by the photometric residual
against the map (the tracker's loss at its start, the frontend's pose, and at its result), the
map's pose by the reprojection of the frame's landmarks, and both by their distance from the
constant-velocity prediction; the better one stays, and a frame neither explains is lost. Pure functions over poses and losses."""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from nicer_stream.geometry.se3 import invert


@dataclass(frozen=True)
class Verdict:
    """`keep`: "map" (the refined pose), "frontend" or "lost"; `why`: one line for the log."""

    keep: str
    why: str


def motion_distance(T: torch.Tensor, T_motion: torch.Tensor) -> float:
    """Translation between T_world_cam `T` and the constant-velocity prediction `T_motion`."""
    return float((invert(T_motion) @ T)[:3, 3].norm())


def judge_disagreement(loss_map: float, loss_front: float, T_map: torch.Tensor, T_front: torch.Tensor,
                       T_motion: torch.Tensor, recent_losses: list[float], loss_jump: float,
                       evidence_ratio: float, reproj_map_px: float = 0.0,
                       reproj_limit_px: float = math.inf) -> Verdict:
    """The pose to keep when the refined pose `T_map` (photometric loss `loss_map`) disagrees with
    the frontend's `T_front` (loss `loss_front` against the same map). A frame whose best loss is
    above `loss_jump` times the recent median is lost. Each pose was fitted to its own evidence
    (the refined one minimises the loss, the frontend's the landmarks' reprojection), so the
    map's pose must also place the frame's landmarks: with their median reprojection error
    `reproj_map_px` above `reproj_limit_px` the frontend's pose stays. Then the map's pose wins
    when its loss is below `evidence_ratio` times the frontend's, or when the losses are within
    that ratio and it is nearer the motion prediction `T_motion`."""
    best = min(loss_map, loss_front)
    if not math.isfinite(best):
        return Verdict("lost", "no finite photometric loss at either pose")
    if len(recent_losses) >= 3:
        med = sorted(recent_losses)[len(recent_losses) // 2]
        if best > loss_jump * med:
            return Verdict("lost", f"neither pose explains the frame (loss {best:.3f}, {best / med:.1f}x the recent median)")
    if reproj_map_px > reproj_limit_px:
        return Verdict("frontend", f"the map's pose misplaces the frame's landmarks (median {reproj_map_px:.1f} px, "
                                   f"limit {reproj_limit_px:.1f})")
    if loss_map < evidence_ratio * loss_front:
        return Verdict("map", f"the map's pose explains the frame better (loss {loss_map:.3f} vs {loss_front:.3f})")
    if loss_front < evidence_ratio * loss_map:
        return Verdict("frontend", f"the frontend's pose explains the frame better (loss {loss_front:.3f} vs {loss_map:.3f})")
    d_map, d_front = motion_distance(T_map, T_motion), motion_distance(T_front, T_motion)
    if d_map < d_front:
        return Verdict("map", f"losses alike; the map's pose is nearer the motion ({d_map:.3g} vs {d_front:.3g})")
    return Verdict("frontend", f"losses alike; the frontend's pose is nearer the motion ({d_front:.3g} vs {d_map:.3g})")


class DisagreementStreaks:
    """Runs of refined frames in a row on which the frontend and the map disagreed: a run of
    `report_after` is logged once and counted (a frontend drifting from the map, or a map that
    no longer fits the frames)."""

    def __init__(self, report_after: int = 3) -> None:
        self.report_after = report_after
        self.run = 0
        self.streaks: list[tuple[int, int]] = []  # (first frame, length) of each reported run
        self._first = -1

    def observe(self, index: int, disagree: bool) -> bool:
        """Record frame `index`; True when this frame completes a reportable run."""
        if not disagree:
            self.run = 0
            return False
        self._first = index if self.run == 0 else self._first
        self.run += 1
        if self.run == self.report_after:
            self.streaks.append((self._first, self.run))
            return True
        if self.run > self.report_after:
            self.streaks[-1] = (self._first, self.run)
        return False
