"""What the SLAM's parts share: the stored frames, keyframes, poses and input order, and the map
from the start on. The parts (startup, keyframes, tracking policy, mapping calls) each read and
write it; `SlamSystem` wires them. Plain data and the trajectory read from it."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterable

import numpy as np
import torch

from nicer_stream.frontend.frontend import FrontendPose
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.slam.events import TrackingWarning
from nicer_stream.slam.pose_corrections import spread_corrections
from nicer_stream.tracking.tracker import Tracker
from nicer_stream.types import Priors


def attach_flows(priors: Priors, frames: Iterable[MapFrame]) -> None:
    """Each flow of `priors` into the frame it starts at, among `frames` (each frame once)."""
    for f in {id(f): f for f in frames}.values():
        f.add_flows(priors)


@dataclass
class SlamState:
    frames: dict[int, MapFrame] = field(default_factory=dict)
    """The keyframes, the first frame and the latest frame."""
    keyframes: list[int] = field(default_factory=list)
    poses: dict[int, torch.Tensor] = field(default_factory=dict)
    """T_world_cam (4, 4) float32 of every frame with a pose, as tracking goes on from them."""
    timestamps: dict[int, float] = field(default_factory=dict)
    order: list[int] = field(default_factory=list)
    """Every frame with a pose, in input order."""
    lost_frames: list[int] = field(default_factory=list)
    """Frames whose pose is not trusted: never keyframes, never start a mapping call."""
    mapped_frames: set[int] = field(default_factory=set)
    """Frames some mapping call fitted the map to (the others are held out)."""
    unrefined: set[int] = field(default_factory=set)
    """Frames whose pose is the frontend's alone (`tracking.refine = 'keyframes'`)."""
    frontend_at: dict[int, FrontendPose] = field(default_factory=dict)
    """The frontend's estimate each tracked frame started from."""
    replay: set[int] = field(default_factory=set)
    """Held frames the start has yet to record: flows to them stay in the stored frames."""
    scale_rule: tuple[float, float] | None = None
    """(w, q) of the first frame's depth prior, which sets the metric scale."""
    warnings: list[TrackingWarning] = field(default_factory=list)
    """For the caller's sinks: `step` returns and clears them."""
    deferred_flows: Callable[[], Priors] | None = None
    """The latest frame's flows `step` did not need yet (computed once, when asked)."""
    model: SceneModel | None = None
    beta: BetaField | None = None
    bound: SceneBound | None = None
    mapper: Mapper | None = None
    tracker: Tracker | None = None
    """The map and its optimisers, from the start on (None before)."""

    def history(self) -> list[torch.Tensor]:
        """The last two poses in input order (the motion model's input)."""
        return [self.poses[i] for i in self.order[-2:]]

    def attach_deferred(self, mf: MapFrame) -> None:
        """The deferred flows into the latest frame `mf` and the stored frames they start at; once."""
        if self.deferred_flows is None:
            return
        priors, self.deferred_flows = self.deferred_flows(), None
        attach_flows(priors, [*self.frames.values(), mf])

    def trajectory(self) -> tuple[list[float], list[np.ndarray]]:
        """(timestamps, T_world_cam float64) of every frame so far, in input order: the frames that
        hold the frontend's pose moved with the map's corrections of the keyframes around them
        (`pose_corrections.py`; the poses tracking goes on from are not changed)."""
        anchors = (self.mapped_frames | set(self.keyframes)) & set(self.poses)
        # In the poses' float32, as tracking started from them (an unmoved keyframe: no correction).
        frontend = {k: torch.as_tensor(f.T_world_cam, dtype=self.poses[k].dtype, device=self.poses[k].device)
                    for k, f in self.frontend_at.items() if k in self.poses}
        poses = spread_corrections(self.order, self.poses, frontend, anchors, self.unrefined)
        return [self.timestamps[i] for i in self.order], [poses[i].double().cpu().numpy() for i in self.order]
