"""How a frame gets its pose: the seed (the frontend's checked pose, else the motion model or
flow PnP), whether it is refined against the map (`tracking.refine`), whether the refinement is
trusted (`motion.tracking_failure`; with a seed from the frontend, their disagreement settled by
evidence, `disagreement.py`), and what an untrusted frame does: it is lost and keeps the frontend's
(else the motion model's) pose, or, as a keyframe with `rejected_keyframe = 'frontend'`, stays a
keyframe at the frontend's pose."""
from __future__ import annotations

import logging
import math

import torch

from nicer_stream.config import SlamConfig
from nicer_stream.frontend.frontend import FrontendPose
from nicer_stream.frontend.health import reprojection_error
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.slam.disagreement import DisagreementStreaks, judge_disagreement
from nicer_stream.slam.events import Event, FrameTracked, TrackingWarning
from nicer_stream.slam.frontend_link import FrontendLink, FrontendSeed
from nicer_stream.slam.keyframes import KeyframePolicy
from nicer_stream.slam.motion import frontend_disagreement, predict_pose, tracking_failure
from nicer_stream.slam.state import SlamState
from nicer_stream.tracking.flow_init import pose_from_flows
from nicer_stream.types import Frame

log = logging.getLogger(__name__)


class TrackingPolicy:
    def __init__(self, cfg: SlamConfig, state: SlamState, front: FrontendLink, keyframing: KeyframePolicy) -> None:
        self.cfg, self.state, self.front, self.keyframing = cfg, state, front, keyframing
        self.recent_losses: list[float] = []  # the last refined frames' losses (the loss-jump check)
        self.frontend_kept: set[int] = set()  # lost frames whose pose is the frontend's
        self.verdicts = {"map": 0, "frontend": 0, "lost": 0}  # disagreements settled by evidence
        self.disagreements = DisagreementStreaks()

    def frontend_trusts(self, index: int) -> bool:
        """Whether the frontend may triangulate from frame `index`'s pose: it is not lost, or it
        is the frontend's own (consistent with its landmarks)."""
        return index not in self.state.lost_frames or index in self.frontend_kept

    def track(self, mf: MapFrame) -> FrameTracked:
        """The pose of the next frame in order, `mf`, against the map."""
        s, n = self.state, len(self.state.order) + 1
        history = s.history()
        T_pred, seed = self._seed(mf)
        self.keyframing.decide(mf.index, T_pred, mf.timestamp, seed.pose.median_depth if seed else None)
        if (seed is not None and self.cfg.tracking.refine == "keyframes" and not self.keyframing.due(n, mf.index)
                and not self.keyframing.mapping_slot(n)):
            # Neither a keyframe nor mapped from: the frontend's pose stands.
            s.poses[mf.index] = T_pred.detach()
            s.unrefined.add(mf.index)
            return FrameTracked(mf.index, mf.timestamp, T_pred.detach().double().cpu().numpy(), math.nan, 0.0)
        res = s.tracker.track(mf, T_pred)
        reason = tracking_failure(res.T_world_cam, T_pred, res.loss, self.recent_losses, self.cfg.tracking)
        if reason is None and seed is None and self.front.frontend is not None and len(s.keyframes) > 2:
            log.info("frame %d: the frontend has no pose (too few tracked landmarks)", mf.index)
        T = T_pred if reason else res.T_world_cam
        if reason is None and seed is not None:
            T, reason = self._settle(mf.index, res, T_pred, predict_pose(history, "constant_velocity"),
                                     history[-1], seed)
        reason = self._untrusted(mf.index, n, reason, seed, res.loss)
        s.poses[mf.index] = T.detach()
        return FrameTracked(mf.index, mf.timestamp, T.detach().double().cpu().numpy(), res.loss, res.seconds, reason)

    def _seed(self, mf: MapFrame) -> tuple[torch.Tensor, FrontendSeed | None]:
        """Where tracking starts: the frontend's checked pose, else the motion model's
        prediction (or flow PnP from it with `tracking.init = 'flow'`)."""
        s = self.state
        T_pred = predict_pose(s.history(), self.cfg.tracking.init)
        seed = self.front.estimate(mf.index, T_pred)
        if seed is not None:
            T_pred = torch.as_tensor(seed.pose.T_world_cam, dtype=T_pred.dtype, device=T_pred.device)
            s.frontend_at[mf.index] = seed.pose
        elif self.cfg.tracking.init == "flow":
            s.attach_deferred(mf)
            T_pred = self._flow_init(mf, T_pred)
        return T_pred, seed

    def _untrusted(self, index: int, n: int, reason: str | None, seed: FrontendSeed | None, loss: float) -> str | None:
        """What a frame whose refinement failed (`reason`) does; the reason it is lost, or None."""
        if reason and seed is not None:
            self.frontend_kept.add(index)  # its own pose: consistent with its landmarks
        if (reason and seed is not None and self.cfg.tracking.rejected_keyframe == "frontend"
                and self.keyframing.due(n, index)):
            log.warning("frame %d: refinement rejected (%s): the keyframe keeps the frontend's pose", index, reason)
            return None  # not lost: the frame stays a keyframe (its loss does not enter the running median)
        if reason:
            self.state.lost_frames.append(index)
            log.warning("frame %d: tracking lost (%s): using the %s pose", index, reason,
                        "frontend's" if seed is not None else "motion model's")
        else:
            self.recent_losses = (self.recent_losses + [loss])[-10:]
        return reason

    def _settle(self, index: int, res, T_front: torch.Tensor, T_motion: torch.Tensor, T_prev: torch.Tensor,
                seed: FrontendSeed) -> tuple[torch.Tensor, str | None]:
        """The refined pose `res` against the frontend's `T_front` (the tracker's start): when they
        disagree beyond `frontend.max_disagreement_*`, the pose the evidence favours
        (`judge_disagreement`); (pose, reason the frame is not trusted or None)."""
        gap = frontend_disagreement(res.T_world_cam, T_front, T_prev, seed.pose.median_depth, self.cfg.frontend)
        if self.disagreements.observe(index, gap is not None):
            msg = f"the frontend and the map disagree on {self.disagreements.run} refined frames in a row"
            log.warning("frame %d: %s", index, msg)
            self.state.warnings.append(TrackingWarning(index, "disagreement", msg))
        if gap is None:
            return res.T_world_cam, None
        X, luv = seed.points, seed.pixels
        reproj = reprojection_error(res.T_world_cam.double().cpu().numpy(), X, luv, self.front.intr) if len(X) else 0.0
        v = judge_disagreement(res.loss, res.initial_loss, res.T_world_cam, T_front, T_motion, self.recent_losses,
                               self.cfg.tracking.loss_jump, self.cfg.frontend.evidence_ratio, reproj,
                               self.cfg.frontend.reproj_px)
        self.verdicts[v.keep] += 1
        log.info("frame %d: %s; %s: %s pose kept", index, gap, v.why, v.keep if v.keep != "lost" else "no")
        if v.keep == "map":
            self.front.distrusted.add(index)  # the frontend adopts the map's pose of this frame
            return res.T_world_cam, None
        return T_front, (gap if v.keep == "frontend" else v.why)

    def _failure(self, res, T_pred: torch.Tensor, T_prev: torch.Tensor, front: FrontendPose | None) -> str | None:
        """Why the tracker's result `res` must not be trusted (None: it may): a tracking loss
        against the start `T_pred`, or, with the frontend's estimate `front` (whose pose `T_pred`
        is), a disagreement with it; `T_prev` is the previous frame's pose."""
        reason = tracking_failure(res.T_world_cam, T_pred, res.loss, self.recent_losses, self.cfg.tracking)
        if reason is None and front is not None:
            reason = frontend_disagreement(res.T_world_cam, T_pred, T_prev, front.median_depth, self.cfg.frontend)
        return reason

    def refine_last(self) -> list[Event]:
        """`refine = 'keyframes'`: the closing call maps the latest frame, so its frontend pose
        is refined against the map first, with the checks every keyframe's refinement passes (a
        second FrameTracked event carries the new pose; none when they reject it)."""
        s = self.state
        last = s.order[-1]
        if last not in s.unrefined or last not in s.frames:
            return []
        s.unrefined.discard(last)
        T_front = s.poses[last]
        res = s.tracker.track(s.frames[last], T_front)
        front = s.frontend_at.get(last) if len(s.order) > 1 else None
        reason = self._failure(res, T_front, s.poses[s.order[-2]] if front else T_front, front)
        if reason is not None:  # the pose stays as reported: no new event
            log.info("frame %d: refinement before the closing mapping rejected (%s): frontend pose kept", last, reason)
            return []
        s.poses[last] = res.T_world_cam.detach()
        return [FrameTracked(last, s.timestamps[last], s.poses[last].double().cpu().numpy(), res.loss,
                             res.seconds, None)]

    def _flow_init(self, mf: MapFrame, T_prev: torch.Tensor) -> torch.Tensor:
        """PnP pose from the stored frames' flows to `mf` (else `T_prev`)."""
        s = self.state
        sources = [(f, s.poses[k]) for k, f in s.frames.items() if mf.index in f.flows]
        T = pose_from_flows(sources, mf, T_prev, s.tracker.model, s.tracker.beta, s.tracker.render,
                            self.cfg.tracking.flow_points, s.tracker.gen)
        if T is None:
            log.info("frame %d: no flow PnP solution: tracking from the previous pose", mf.index)
            return T_prev
        return T

    def skip_corrupt(self, frame: Frame, device: torch.device) -> FrameTracked:
        """A frame with non-finite pixels: pose from the motion model, never mapped."""
        s, reason = self.state, "non-finite pixels in the input frame"
        log.warning("frame %d: %s: skipped (pose from the motion model)", frame.index, reason)
        s.lost_frames.append(frame.index)
        T = predict_pose(s.history(), self.cfg.tracking.init) if s.order else torch.eye(4, device=device)
        s.poses[frame.index] = T
        s.order.append(frame.index)
        s.timestamps[frame.index] = frame.timestamp
        return FrameTracked(frame.index, frame.timestamp, T.double().cpu().numpy(), float("nan"), 0.0, reason)
