"""The streaming SLAM system: `step(frame)` per frame, `finish()` at the end.

A short orchestrator over one shared `SlamState` (state.py) and the parts that each own one
decision: how the map starts (startup.py, first_map.py), how a frame gets its pose
(tracking_policy.py), which frames become keyframes and start mapping calls and how frames are
stored (keyframes.py), the mapping calls (map_calls.py) and the classical frontend's part
(frontend_link.py). Tracking runs in the caller's thread; mapping calls are jobs run by an
injected executor: inline by default (deterministic), or on the runtime's worker, tracking then
reads the last published map snapshot. No ground truth enters: `step` refuses frames that carry
any (priors are computed beforehand by runtime.prior_stage).
"""
from __future__ import annotations

import operator
from dataclasses import replace
from typing import Callable

import numpy as np
import torch

from nicer_stream.config import SlamConfig
from nicer_stream.errors import UserError
from nicer_stream.frontend.frontend import ClassicalFrontend
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mesh.visibility import DepthView
from nicer_stream.model.scene import SceneModel
from nicer_stream.priors.keyframe_stereo import StereoPriors, fusion_params
from nicer_stream.render.beta import BetaField
from nicer_stream.slam.events import Event, FrameTracked, MapUpdated
from nicer_stream.slam.first_map import new_map, start_bound, start_scale
from nicer_stream.slam.frontend_link import FrontendLink
from nicer_stream.slam.keyframes import KeyframePolicy
from nicer_stream.slam.map_calls import MapCalls, MappingProgress
from nicer_stream.slam.map_jobs import MappingExecutor
from nicer_stream.slam.startup import StartPhase, StartPlan, Startup
from nicer_stream.slam.state import SlamState, attach_flows
from nicer_stream.slam.tracking_policy import TrackingPolicy
from nicer_stream.types import Frame, Intrinsics, Priors


class _Part:
    """Read-only access to a part's attribute under the name callers know (`slam.poses`)."""

    def __init__(self, path: str) -> None:
        self.path, self.get = path, operator.attrgetter(path)

    def __get__(self, obj, owner=None):
        return self if obj is None else self.get(obj)

    def __set__(self, obj, value) -> None:
        raise AttributeError(f"set {self.path} instead")


class SlamSystem:
    """Wires the parts and runs a frame through them.

    `progress`, when given, is called with a label ("first mapping (frames 0,10)",
    "mapping @ frame 15", "closing mapping @ frame 19") as each mapping call starts and
    returns the callback that call reports its iterations to; the caller does the printing."""

    frames, keyframes, poses, order = (_Part(f"state.{n}") for n in ("frames", "keyframes", "poses", "order"))
    timestamps, lost_frames, mapped_frames = (_Part(f"state.{n}") for n in ("timestamps", "lost_frames", "mapped_frames"))
    model, beta, bound, mapper, tracker = (_Part(f"state.{n}") for n in ("model", "beta", "bound", "mapper", "tracker"))
    scale_rule = _Part("state.scale_rule")
    pending, unposed, init_note, scale_from = (_Part(f"startup.{n}") for n in ("pending", "unposed", "init_note", "scale_from"))
    frontend, frontend_seconds, health = _Part("front.frontend"), _Part("front.seconds"), _Part("front.health")
    mapping, map_version, mapped_iters = _Part("maps.executor"), _Part("maps.version"), _Part("maps.iters")
    mapping_wait_s = _Part("maps.wait_s")

    def __init__(self, cfg: SlamConfig, device: str = "cpu",
                 progress: Callable[[str], MappingProgress | None] | None = None,
                 stereo: bool = False, should_stop: Callable[[], bool] | None = None,
                 mapping: MappingExecutor | None = None, fuse_mono: bool = False) -> None:
        # Modes and ranges were checked by the config itself (config.py `__post_init__`).
        self.cfg, self.device, self.state = cfg, torch.device(device), SlamState()
        # `--priors stereo`: keyframe depth/normal priors by plane sweep before each mapping call;
        # `fuse_mono` (a monocular provider with `stereo.mono_fusion`): the sweep's depth with the
        # provider's fitted to it.
        self.stereo = StereoPriors(cfg.stereo if stereo else fusion_params(cfg.stereo)) if stereo or fuse_mono else None
        # 'auto': the frontend where the depth prior needs good poses (stereo) or starts the SLAM.
        use = cfg.tracking.frontend == "classical" or (cfg.tracking.frontend == "auto" and self.stereo is not None)
        self.front = FrontendLink(ClassicalFrontend(cfg.frontend) if use else None, self.state)
        self.startup = Startup(cfg, self.state, self.front)
        self.keyframing = KeyframePolicy(cfg, self.state, self.front)
        self.tracking = TrackingPolicy(cfg, self.state, self.front, self.keyframing)
        self.maps = MapCalls(cfg, self.state, self.front, self.stereo, mapping, progress, should_stop)

    def step(self, frame: Frame, priors: Priors | None = None,
             flows: Callable[[], Priors] | None = None) -> list[Event]:
        """Track `frame` (GT-free), add it as a keyframe / map when the schedule says so.
        With a two-view start the first frames are held until the second view arrives; their
        events come then. `flows`, when given, returns the frame's flows that `priors` lacks:
        called only when the frame needs them (it becomes a keyframe or is mapped, or has no
        frontend pose to start tracking from), or at once before the start and without a frontend."""
        if frame.gt_pose is not None or frame.gt_depth is not None:
            raise UserError("SlamSystem.step got a frame with ground truth: pass frame.without_ground_truth()")
        s = self.state
        done = self.maps.collect()  # mapping calls that finished on the worker since the last frame
        s.deferred_flows = flows
        if flows is not None and (self.startup.phase is not StartPhase.RUNNING or self.front.frontend is None):
            priors = replace(priors, flows=priors.flows + flows().flows) if priors is not None else flows()
            s.deferred_flows = None
        events = done + self._step(frame, priors)
        warnings, s.warnings = s.warnings, []
        return events + warnings

    def _step(self, frame: Frame, priors: Priors | None) -> list[Event]:
        mf = MapFrame.from_frame(frame, priors, self.device) if np.isfinite(frame.rgb).all() else None
        if mf is not None:
            if self.stereo is not None:
                self.stereo.observe(frame.index, frame.rgb, frame.detail)
            self.front.observe(frame)
            if priors is not None:  # flows from the stored (and held) frames to this one
                attach_flows(priors, [*self.state.frames.values(), *self.startup.pending])
        if self.startup.phase is not StartPhase.RUNNING:
            got = self.startup.offer(mf, frame)
            if isinstance(got, StartPlan):
                return self._start(got)
            if got is not None:  # held
                return got
        return self._advance(mf, frame)

    def _start(self, plan: StartPlan) -> list[Event]:
        """The map from the start's frames, then the held frames through tracking in input order."""
        events = self._first_map(plan) + self._record(plan.first, plan.first_raw)
        for m, f in plan.rest:
            known = self.state.poses[m.index] if plan.second is not None and m is plan.second else None
            if known is None and self.maps.should_stop():
                continue  # stopping: no tracking; the frames with a pose are kept
            events += self._advance(m, f, known)
        return events

    def _first_map(self, plan: StartPlan) -> list[Event]:
        """Bound, scene and the first mapping call: `first` at the identity (and `second` at the
        two-view pose, both priors' (w, q) fixed from then on)."""
        s, first = self.state, plan.first
        s.poses[first.index] = torch.eye(4, device=self.device)
        if plan.view is not None:
            s.poses[plan.second.index] = torch.as_tensor(plan.view.T_world_second, dtype=torch.float32,
                                                         device=self.device)
        s.scale_rule = start_scale(self.cfg, first, plan.second, plan.view)
        s.bound = start_bound(self.cfg, first, plan.view, plan.points, s.scale_rule)
        for f in plan.window:
            self.front.set_pose(f.index, s.poses[f.index], True)
        s.model, s.beta, s.mapper, s.tracker = new_map(self.cfg, s.bound, self.device)
        s.frames[first.index] = first
        mapped = self.maps.first(plan.window, None if plan.view is not None else s.scale_rule)
        if self.cfg.loss.slam_prior_alignment == "map" and plan.view is None:
            first.depth_scale_shift = s.scale_rule
        return [FrameTracked(first.index, first.timestamp, s.poses[first.index].double().cpu().numpy(), 0.0, 0.0),
                mapped]

    def _advance(self, mf: MapFrame | None, frame: Frame, T_known: torch.Tensor | None = None) -> list[Event]:
        """One frame through the normal schedule: track (or take `T_known`), store, keyframe, map."""
        if mf is None:
            return [self.tracking.skip_corrupt(frame, self.device)]
        if T_known is not None:
            self.state.poses[mf.index] = T_known
            tracked = FrameTracked(mf.index, mf.timestamp, T_known.double().cpu().numpy(), 0.0, 0.0)
        else:
            tracked = self.tracking.track(mf)
        return [tracked] + self._record(mf, frame)

    def _record(self, mf: MapFrame, frame: Frame) -> list[Event]:
        """Book a frame whose pose is set: order, storage, keyframe and mapping schedule. A frame
        whose pose is not trusted never becomes a keyframe nor starts a mapping call."""
        s, i = self.state, frame.index
        s.replay.discard(i)
        s.order.append(i)
        s.timestamps[i] = frame.timestamp
        self.keyframing.store(mf)
        trusted = i not in s.lost_frames
        is_kf, maps = self.keyframing.schedule(i, frame.timestamp, trusted)
        self.front.set_pose(i, s.poses[i], self.tracking.frontend_trusts(i))
        if s.model is not None:  # a frame the frontend does not trust is left alone by it
            self.front.seed_from_map(i, self.map_view(), self.cfg.render, is_kf and trusted)
        if is_kf or maps or self.maps.due:  # its flows are needed (before any keyframe is halved:
            s.attach_deferred(s.frames[i])  # flows into those are dropped)
        events = self.keyframing.add(i, frame.timestamp) if is_kf and trusted else []
        if trusted and (maps or self.maps.due):
            events += self.maps.at(i)
        return events

    def finish(self) -> list[Event]:
        """Start from what is held if the sequence ended first; refine the latest frame if only
        the frontend posed it; the closing mapping call (`MapCalls.close`)."""
        if self.startup.phase is StartPhase.HOLDING:
            return self._start(self.startup.begin(None, None)) + self.finish()
        s = self.state
        if s.model is None:
            return []
        if s.order and s.order[-1] in s.frames:  # the closing call maps the latest frame
            s.attach_deferred(s.frames[s.order[-1]])
        events = self.wait_for_mapping() + self.tracking.refine_last()
        return events + self.maps.close() + self.wait_for_mapping()

    def wait_for_mapping(self) -> list[MapUpdated]:
        """Wait for the mapping call in hand (if any) and apply it: the live map is then final."""
        return self.maps.collect(wait=True)

    # -- results ---------------------------------------------------------------------
    def measured_views(self, intr: Intrinsics) -> list[DepthView]:
        """The keyframes' measured stereo depth at their current poses, for the mesh's culling
        (`scene_mesh(measured=...)`); [] without plane-sweep stereo. Call it on the SLAM thread."""
        if self.stereo is None:
            return []
        poses = {k: self.state.poses[k].double().cpu().numpy() for k in self.stereo.measured if k in self.state.poses}
        return self.stereo.measured_views(poses, intr)

    def map_view(self) -> tuple[SceneModel, BetaField]:
        """The map as tracking reads it: the live one inline, else the last published snapshot
        (safe to render from the caller's thread while mapping runs)."""
        return self.maps.view()

    def health_summary(self) -> dict:
        """What went wrong in tracking, for `summary.json`: the frontend's health reports by kind
        (and the first 100), the disagreements settled by evidence, the frames the start passed
        over, the disagreement streaks, the landmarks the frontend recognised after they had left
        its window, why each keyframe was taken."""
        health, tracking = self.front.health, self.tracking
        return {"frontend_reports": health.counts(),
                "frontend_report_lines": [str(r) for r in health.reports[:100]],
                "disagreements_kept": dict(tracking.verdicts),
                "unposed_before_start": list(self.startup.unposed),
                "disagreement_streaks": [{"first_frame": a, "frames": n} for a, n in tracking.disagreements.streaks],
                "scale_off_map": [{"frame": i, "ratio": round(r, 3)} for i, r in self.front.scale_off_map],
                "landmarks_recognised": self.front.frontend.recognised if self.front.frontend is not None else 0,
                "keyframe_reasons": self.keyframing.reasons()}

    def trajectory(self) -> tuple[list[float], list[np.ndarray]]:
        """(timestamps, T_world_cam float64) of every frame so far, in input order (`SlamState.trajectory`)."""
        return self.state.trajectory()
