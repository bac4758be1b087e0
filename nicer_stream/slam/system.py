"""The streaming SLAM system: `step(frame)` per frame, `finish()` at the end.

Tracking runs in the caller's thread; mapping calls are jobs (slam/map_jobs.py) run by an
injected executor: inline by default (tracking and mapping in order, deterministic), or on
the runtime's worker, tracking then reads the last published map snapshot and never waits
for a mapping call except at start-up and at the end. No ground truth enters: `step` refuses
frames that carry any (priors are computed beforehand by runtime.prior_stage).
"""
from __future__ import annotations

import itertools
import logging
import math
import random
import time
from contextlib import contextmanager
from dataclasses import replace
from typing import Callable

import numpy as np
import torch

from nicer_stream.config import SlamConfig
from nicer_stream.frontend.frontend import ClassicalFrontend, FrontendPose, TwoViewTracks
from nicer_stream.frontend.health import FrontendHealth, reprojection_error
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.depth_shift import shift_from_normals
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.mapping.prior_alignment import align_prior_to_map, align_to_widest_partner
from nicer_stream.mesh.visibility import DepthView
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.model.bound_estimate import bound_around, bound_from_config, bound_from_depth
from nicer_stream.model.geometry import initial_sphere
from nicer_stream.slam.events import Event, FrameTracked, KeyframeAdded, MapUpdated, TrackingWarning
from nicer_stream.slam.map_jobs import InlineMapping, MapJob, MappingExecutor, MapResult, job_frames, take_snapshot
from nicer_stream.slam.motion import frontend_disagreement, predict_pose, tracking_failure
from nicer_stream.slam.pose_corrections import spread_corrections
from nicer_stream.priors.keyframe_stereo import StereoPriors, fusion_params
from nicer_stream.slam.keyframes import KeyframeRule, KeyframeSelector
from nicer_stream.slam.tracking_policy import DisagreementStreaks, judge_disagreement
from nicer_stream.slam.two_view import TwoView, two_view_from_tracks, two_view_init
from nicer_stream.slam.window import ba_frames, select_window
from nicer_stream.tracking.flow_init import pose_from_flows
from nicer_stream.tracking.tracker import Tracker
from nicer_stream.errors import UserError
from nicer_stream.types import Frame, Intrinsics, Priors

log = logging.getLogger(__name__)

# (iteration, iterations, loss) after each mapping iteration (Mapper.optimise's `progress`).
MappingProgress = Callable[[int, int, float], None]


def first_scale_shift(mf: MapFrame, median_m: float) -> tuple[float, float]:
    """(w, q) of the first frame's depth prior (prior = w * depth + q): q from the normal
    prior's agreement (0 without one), w so that the median depth is `median_m` metres."""
    q = 0.0
    if mf.normal_prior is not None:
        q = shift_from_normals(mf.depth_prior.cpu().numpy(), mf.normal_prior.cpu().numpy(), mf.intr)
    valid = mf.depth_prior[mf.depth_prior > q]
    return float((valid - q).median()) / median_m, q


class SlamSystem:
    """Owns the scene, the optimisers, keyframes and the trajectory.

    `progress`, when given, is called with a label ("first mapping (frames 0,10)",
    "mapping @ frame 15", "closing mapping @ frame 19") as each mapping call starts and
    returns the callback that call reports its iterations to; the caller does the printing."""

    def __init__(self, cfg: SlamConfig, device: str = "cpu",
                 progress: Callable[[str], MappingProgress | None] | None = None,
                 stereo: bool = False, should_stop: Callable[[], bool] | None = None,
                 mapping: MappingExecutor | None = None, fuse_mono: bool = False) -> None:
        # Modes and ranges were checked by the config itself (config.py `__post_init__`).
        self.cfg, self.device = cfg, torch.device(device)
        # `--priors stereo`: keyframe depth/normal priors by plane sweep before each mapping call;
        # `fuse_mono` (a monocular provider with `stereo.mono_fusion`): the sweep's depth with the
        # provider's fitted to it.
        self.stereo = StereoPriors(cfg.stereo if stereo else fusion_params(cfg.stereo)) if stereo or fuse_mono else None
        self.progress = progress
        # Polled by mapping iterations and between the held frames of the two-view start:
        # a stop request ends them early (the caller then writes what exists).
        self.should_stop = should_stop or (lambda: False)
        self.mapped_iters = 0  # mapping iterations done (0: the scene is still the initial sphere)
        self.mapping = mapping or InlineMapping()
        self.map_version = 0  # mapping calls applied; tracking reads this version of the map
        self.mapped_frames: set[int] = set()  # frames some mapping call fitted the map to (others are held out)
        self._map_due = False  # a call the schedule asked for while the worker was busy
        self.mapping_wait_s = 0.0  # the caller's seconds in mapping: inline calls and waits for the worker
        self.rng = random.Random(cfg.seed)
        self.model: SceneModel | None = None
        self.beta: BetaField | None = None
        self.mapper: Mapper | None = None
        self.tracker: Tracker | None = None
        self.bound: SceneBound | None = None
        self.frames: dict[int, MapFrame] = {}  # keyframes + the latest frame
        self.keyframes: list[int] = []
        self.poses: dict[int, torch.Tensor] = {}
        self.timestamps: dict[int, float] = {}
        self.order: list[int] = []
        self.lost_frames: list[int] = []
        self.recent_losses: list[float] = []
        self.scale_rule: tuple[float, float] | None = None
        self.pending: list[MapFrame | None] = []  # held for the two-view start (None: corrupt)
        self._replay: set[int] = set()  # held frames the start has yet to record (flows to them stay)
        self.pending_raw: list[Frame] = []
        self.unposed: list[int] = []  # frames the start passed over (no pose: `_slide_start`)
        self.init_note = ""
        self.scale_from = "depth-prior median"  # what `first_depth_median_m` sets: the first frame's ...
        # 'auto': the frontend where the depth prior needs good poses (stereo) or starts the SLAM.
        use = cfg.tracking.frontend == "classical" or (cfg.tracking.frontend == "auto" and self.stereo is not None)
        self.frontend = ClassicalFrontend(cfg.frontend) if use else None
        self.frontend_seconds = 0.0
        self._fview = None  # (frame index, frontend two-view result) of the start without priors
        self._frontend_kept: set[int] = set()  # lost frames whose pose is the frontend's
        self._unrefined: set[int] = set()  # frames whose pose is the frontend's alone (`tracking.refine`)
        self._frontend_at: dict[int, FrontendPose] = {}  # the frontend's estimate each frame started from
        self._keyframe_owed = False  # a keyframe slot's frame failed its check (`tracking.refine`)
        self._halved: set[int] = set()  # keyframes kept at half resolution (`full_res_keyframes`)
        self.health = FrontendHealth()  # the frontend's own checks of its poses
        m = cfg.mapping
        self.keyframe_view = KeyframeSelector(KeyframeRule(
            m.keyframe_min_overlap, m.keyframe_max_baseline, m.keyframe_max_rotation_deg,
            m.keyframe_max_gap_s)) if m.keyframes == "view" else None
        self._kf_reason: dict[int, str | None] = {}  # view keyframes: decided, not yet recorded
        self._scene_depth: float | None = None  # the frontend's latest median landmark depth
        self._distrusted: set[int] = set()  # frames whose frontend pose failed them
        self.verdicts = {"map": 0, "frontend": 0, "lost": 0}  # disagreements settled by evidence
        self.disagreements = DisagreementStreaks()
        self._warnings: list[TrackingWarning] = []  # for the caller's sinks, returned by `step`
        self._more_flows: Callable[[], Priors] | None = None  # the latest frame's deferred flows

    # -- per frame -------------------------------------------------------------------
    def step(self, frame: Frame, priors: Priors | None = None,
             flows: Callable[[], Priors] | None = None) -> list[Event]:
        """Track `frame` (GT-free), add it as a keyframe / map when the schedule says so.
        With `mapping.init = 'two_view'` the first frames are held until the second view
        arrives; their events come then. `flows`, when given, returns the frame's flows that
        `priors` lacks: called only when the frame needs them (it becomes a keyframe or is mapped,
        or has no frontend pose to start tracking from), or at once before the start and
        without a frontend."""
        if frame.gt_pose is not None or frame.gt_depth is not None:
            raise UserError("SlamSystem.step got a frame with ground truth: pass frame.without_ground_truth()")
        done = self._collect()  # mapping calls that finished on the worker since the last frame
        self._more_flows = flows
        if flows is not None and (self.model is None or self.frontend is None or self.pending):
            priors = replace(priors, flows=priors.flows + flows().flows) if priors is not None else flows()
            self._more_flows = None
        events = done + self._step(frame, priors)
        warnings, self._warnings = self._warnings, []
        return events + warnings

    def _step(self, frame: Frame, priors: Priors | None) -> list[Event]:
        mf = MapFrame.from_frame(frame, priors, self.device) if np.isfinite(frame.rgb).all() else None
        if self.stereo is not None and mf is not None:
            self.stereo.observe(frame.index, frame.rgb, frame.detail)
        if self.frontend is not None and mf is not None:
            with self._frontend_timer():
                if frame.detail is not None:  # the source's larger image (`frontend.max_side`)
                    self.frontend.observe(frame.index, frame.detail.grey, frame.detail.intrinsics)
                else:
                    self.frontend.observe(frame.index, frame.rgb, frame.intrinsics)
        if priors is not None and mf is not None:  # flows from stored (and held) frames to this one
            for kf in list(self.frames.values()) + [p for p in self.pending if p is not None]:
                kf.add_flows(priors)
        if self.model is None and self.pending:
            self._slide_start(mf)
        if self.model is None and self._waits(mf):
            self.pending.append(mf)
            self.pending_raw.append(frame)
            if len(self.pending) > 1:
                return []
            # The first frame is a keyframe from the start: priors flow from it to the next ones.
            self.keyframes.append(frame.index)
            if self.frontend is not None:
                self.frontend.pinned = {frame.index}
            return [KeyframeAdded(frame.index)]
        if self.pending:
            return self._start_two_view(mf, frame)
        return self._advance(mf, frame)

    def _slide_start(self, mf: MapFrame | None) -> None:
        """Without a depth prior the start needs tracks the first held view shares with a later
        one: the first view moves to the oldest held frame that still shares enough with `mf`
        (`ClassicalFrontend.stale_first_views`; never onto or past a corrupt frame); the frames it
        passes get no pose."""
        if self.frontend is None or mf is None or self.pending[0] is None or self.pending[0].depth_prior is not None:
            return
        held = list(itertools.takewhile(lambda p: p is not None, self.pending))
        drop = self.frontend.stale_first_views([p.index for p in held], mf.index)
        if not drop:
            return
        passed = [p.index for p in self.pending[:drop] if p is not None]
        self.unposed += passed
        self.pending, self.pending_raw = self.pending[drop:], self.pending_raw[drop:]
        first = self.pending[0].index
        self.keyframes = [first]
        self.frontend.pinned = {first}
        self._fview = None
        log.info("two-view start: frame %d shares too few tracks with frame %d: the start moves to frame %d "
                 "(frames %d-%d get no pose)", passed[0], mf.index, first, passed[0], passed[-1])

    def _attach_flows(self, mf: MapFrame) -> None:
        """The deferred flows of the latest frame `mf` (`step`'s `flows`) into it and the stored
        frames they start at; once."""
        if self._more_flows is None:
            return
        priors, self._more_flows = self._more_flows(), None
        for f in {id(f): f for f in [*self.frames.values(), mf]}.values():
            f.add_flows(priors)

    def _waits(self, mf: MapFrame | None) -> bool:
        """Hold frames for the two-view start: until `init_frames` frames follow the first; without
        a depth prior (the frontend's start) until the frontend sees enough parallax, at most
        `init_max_frames`."""
        init = self.cfg.mapping.init
        if init == "first_frame":
            return False
        if not self.pending:
            if mf is None or (init == "auto" and mf.depth_prior is not None):
                return False  # 'auto' with a depth prior: the first frame's start
            return mf.depth_prior is not None or self.frontend is not None
        if self.pending[0].depth_prior is None:
            if mf is not None and self._frontend_view(mf.index) is not None:
                return False
            return len(self.pending) < self.cfg.mapping.init_max_frames
        return len(self.pending) < self.cfg.mapping.init_frames

    def _frontend_view(self, index: int):
        """The frontend's two-view geometry between the first held frame and `index` (cached)."""
        if self.frontend is None or not self.pending:
            return None
        if self._fview is None or self._fview[0] != index:
            with self._frontend_timer():
                got = self.frontend.two_view(self.pending[0].index, index, self.cfg.loss.first_depth_median_m)
            self._fview = (index, got)
        return self._fview[1]

    def _advance(self, mf: MapFrame | None, frame: Frame, T_known: torch.Tensor | None = None) -> list[Event]:
        """One frame through the normal schedule: track (or take `T_known`), store, keyframe, map."""
        if mf is None:
            return [self._skip_corrupt(frame)]
        events: list[Event] = []
        if self.model is None:
            events += self._initialise(mf)
        elif T_known is not None:
            self.poses[mf.index] = T_known
            events.append(FrameTracked(mf.index, mf.timestamp, T_known.double().cpu().numpy(), 0.0, 0.0))
        else:
            events.append(self._track(mf))
        return events + self._record(mf, frame)

    def _record(self, mf: MapFrame, frame: Frame) -> list[Event]:
        """Book a frame whose pose is set: order, storage, keyframe and mapping schedule."""
        events: list[Event] = []
        i = frame.index
        self._replay.discard(i)
        self.order.append(i)
        self.timestamps[i] = frame.timestamp
        self._store(mf)
        if self.keyframe_view is not None and i not in self._kf_reason:  # not tracked (start, replay)
            self._decide_keyframe(i, self.poses[i], frame.timestamp, None)
        is_kf = self._keyframe_due(len(self.order), i)
        # A frame whose pose is not trusted never becomes a keyframe nor starts a mapping call.
        trusted = i not in self.lost_frames
        # With keyframe-only refinement a failed slot passes to the next frame, which is then
        # refined: otherwise the map would go `keyframe_every` more frames without a keyframe.
        self._keyframe_owed = is_kf and not trusted and self.cfg.tracking.refine == "keyframes"
        self._frontend_pose(i, self.poses[i], trusted or i in self._frontend_kept)
        due = self._mapping_slot(len(self.order)) or (self.keyframe_view is not None and is_kf and len(self.order) > 1)
        if is_kf or due or self._map_due:  # a keyframe or mapped: its flows are needed (before any
            self._attach_flows(self.frames[i])  # keyframe is halved: flows into those are dropped)
        if is_kf and trusted and i not in self.keyframes:
            self.keyframes.append(i)
            events.append(KeyframeAdded(i))
            self._cap_keyframes()
        if is_kf and trusted:  # (the first frame was made a keyframe when it was held)
            self._keyframe_taken(i, frame.timestamp)
        if trusted and (due or self._map_due):
            events += self._collect()  # a call that has just finished frees the worker
            if self.mapping.busy():  # the worker is still on the last call: map at the next frame
                self._map_due = True
            else:
                self._map_due = False
                events += self._map(i, self.cfg.mapping.iters)
        return events

    def _keyframe_slot(self, n: int) -> bool:
        """True when the n-th frame in order (1-based) is due to become a keyframe."""
        return n % self.cfg.mapping.keyframe_every == 1 or self.cfg.mapping.keyframe_every == 1

    def _keyframe_due(self, n: int, index: int) -> bool:
        """True when frame `index`, the n-th in order, is a keyframe slot (or, with view keyframes,
        its view has changed) or takes a failed slot's place."""
        if self.keyframe_view is not None:
            return self._kf_reason.get(index) is not None or self._keyframe_owed
        return self._keyframe_slot(n) or self._keyframe_owed

    def _mapping_slot(self, n: int) -> bool:
        """True when the n-th frame in order (1-based) is due to start a mapping call by the
        frame count (view keyframes: never; each keyframe starts one)."""
        return self.keyframe_view is None and n > 1 and (n - 1) % self.cfg.mapping.every == 0

    def _decide_keyframe(self, index: int, T: torch.Tensor | np.ndarray, timestamp: float, depth: float | None) -> None:
        """View keyframes: whether frame `index` (its pose estimate T, the scene's median depth or
        None) has seen enough change since the last keyframe; the reason is kept."""
        depth = depth or self._scene_depth
        T = T.double().cpu().numpy() if isinstance(T, torch.Tensor) else T
        intr = self.frontend.intr if self.frontend is not None else None
        self._kf_reason[index] = self.keyframe_view.decide(T, timestamp, depth, intr)

    def _view_landmarks(self, index: int) -> np.ndarray | None:
        """The world points (M, 3) of frame `index`'s landmarks, or None: what view keyframes
        look for in later frames."""
        if self.frontend is None or index not in self.frontend.obs:
            return None
        X = self.frontend.landmark_observations(index)[1]
        return X if len(X) else None

    def _keyframe_taken(self, index: int, timestamp: float) -> None:
        if self.keyframe_view is None or index in self.keyframe_view.reasons:
            return
        reason = self._kf_reason.get(index) or "a failed keyframe's place"
        log.info("frame %d: keyframe (%s)", index, reason)
        self.keyframe_view.taken(index, self._view_landmarks(index), self.poses[index].double().cpu().numpy(),
                                 timestamp, reason)
        for k in [k for k in self._kf_reason if k <= index]:
            del self._kf_reason[k]  # decided: bounded memory

    def _refine_unrefined_last(self) -> list[Event]:
        """`refine = 'keyframes'`: the closing call maps the latest frame, so its frontend pose
        is refined against the map first (a second FrameTracked event carries the new pose; none
        when the checks reject it and the frontend's pose stands)."""
        last = self.order[-1]
        if last not in self._unrefined or last not in self.frames:
            return []
        self._unrefined.discard(last)
        T_front = self.poses[last]
        res = self.tracker.track(self.frames[last], T_front)
        # The checks every keyframe's refinement passes (`_track`): the region the last frame sees
        # is the least mapped one (the demo room, seed 1: 53 mm off GT after its refinement).
        front = self._frontend_at.get(last) if len(self.order) > 1 else None
        reason = self._refinement_failure(res, T_front, self.poses[self.order[-2]] if front else T_front, front)
        if reason is not None:  # the pose stays as reported: no new event
            log.info("frame %d: refinement before the closing mapping rejected (%s): frontend pose kept", last, reason)
            return []
        self.poses[last] = res.T_world_cam.detach()
        return [FrameTracked(last, self.timestamps[last], self.poses[last].double().cpu().numpy(), res.loss,
                             res.seconds, None)]

    def finish(self) -> list[Event]:
        """Start from what is held if the sequence ended first; final mapping over the
        latest frame's window: `final_iters` with the poses fixed when set, else `iters` if it
        was not just mapped."""
        if self.pending:
            events = self._start_two_view(None, None)
            return events + self.finish()
        if self.model is None:
            return []
        if self.order and self.order[-1] in self.frames:  # the closing call maps the latest frame
            self._attach_flows(self.frames[self.order[-1]])
        events = self.wait_for_mapping() + self._refine_unrefined_last()
        if self.cfg.mapping.final_iters is not None:
            events += self._map(self.order[-1], self.cfg.mapping.final_iters, bundle_adjust=False, closing=True)
        elif (len(self.order) - 1) % self.cfg.mapping.every != 0 or self._map_due:
            events += self._map(self.order[-1], self.cfg.mapping.iters, closing=True)
        return events + self.wait_for_mapping()

    def wait_for_mapping(self) -> list[MapUpdated]:
        """Wait for the mapping call in hand (if any) and apply it: the live map is then final."""
        return self._collect(wait=True)

    # -- stages ----------------------------------------------------------------------
    def _initialise(self, mf: MapFrame, second: MapFrame | None = None, view: TwoView | None = None,
                    points: np.ndarray | None = None) -> list[Event]:
        """Bound, scene and the first mapping from `mf` at the identity (and `second` at
        the two-view pose, both priors' (w, q) fixed from then on). Without a depth prior, the
        frontend's triangulated `points` (M, 3) world, when given, set the bound."""
        T0 = torch.eye(4, device=self.device)
        self.poses[mf.index] = T0
        cfg = self.cfg
        if view is not None:
            self.scale_rule = view.first_scale_shift
            mf.depth_scale_shift = view.first_scale_shift
            second.depth_scale_shift = view.second_scale_shift
            self.poses[second.index] = torch.as_tensor(view.T_world_second, dtype=torch.float32, device=self.device)
        elif mf.depth_prior is not None and cfg.bound.mode == "auto":
            self.scale_rule = first_scale_shift(mf, cfg.loss.first_depth_median_m)
        if self.scale_rule is not None and cfg.bound.mode == "auto":
            w, q = self.scale_rule
            depth_m = ((mf.depth_prior - q) / w).clamp_min(0).cpu().numpy()
            self.bound = bound_from_depth(depth_m, mf.intr, T0.cpu().numpy().astype(np.float64), cfg.bound)
        elif points is not None and cfg.bound.mode == "auto":
            cams = np.stack([np.zeros(3), view.T_world_second[:3, 3]])
            self.bound = bound_around(np.concatenate([points, cams]), cams, cfg.bound, "landmarks")
        else:
            self.bound = bound_from_config(cfg.bound)
        for f in [mf] + ([second] if second is not None else []):
            self._frontend_pose(f.index, self.poses[f.index], True)
        self.model = SceneModel(cfg.model, self.bound).to(self.device)
        camera = self.bound.normalise(T0[None, :3, 3])[0]
        self.model.geometry.set_sphere(*initial_sphere(cfg.model.sphere_centre, camera, cfg.model.sphere_radius,
                                                       cfg.loss.first_depth_median_m / self.bound.half_extent))
        self.beta = BetaField(cfg.render).to(self.device)
        self.mapper = Mapper(self.model, self.beta, cfg, cfg.seed)
        self.tracker = Tracker(self.model, self.beta, cfg.tracking, cfg.render, cfg.seed)
        self.frames[mf.index] = mf
        window = [mf] if second is None else [mf, second]
        if self.stereo is not None:
            idx = [f.index for f in window]
            self.stereo.update(idx, {f.index: f for f in window}, self.poses, idx, self.bound, self._landmarks())
        # One long call from the sphere, like `map`: the colour grids join early.
        label = f"first mapping (frame{'s' if second else ''} {','.join(str(f.index) for f in window)})"
        stats = self.mapper.optimise(window, self.poses, cfg.mapping.first_iters,
                                     fixed_scale_shift=None if view is not None else self.scale_rule,
                                     progress=self._progress(label), color_start=cfg.mapping.batch_color_start,
                                     stop=self.should_stop)
        self.mapped_iters += stats.iters
        self.mapped_frames.update(f.index for f in window)
        self.mapping_wait_s += stats.seconds
        self.map_version += 1
        if self.mapping.background:  # the worker will change the live map: tracking reads a copy
            self._read_map(take_snapshot(self.model, self.beta, self.map_version))
        if cfg.loss.slam_prior_alignment == "map" and view is None:
            mf.depth_scale_shift = self.scale_rule
        return [
            FrameTracked(mf.index, mf.timestamp, T0.double().cpu().numpy(), 0.0, 0.0),
            MapUpdated(mf.index, tuple(f.index for f in window), stats.loss, stats.iters, stats.seconds, stats.terms,
                       version=self.map_version),
        ]

    def _start_two_view(self, mf: MapFrame | None, frame: Frame | None) -> list[Event]:
        """Initialise from the held frames (+ `mf`, the second view, when given), then run the
        held frames through tracking and the schedule in input order."""
        held = list(zip(self.pending, self.pending_raw)) + ([(mf, frame)] if frame is not None else [])
        if self.frontend is not None:
            self.frontend.pinned = set()
        self.pending, self.pending_raw = [], []
        self._replay = {m.index for m, _ in held[1:] if m is not None}
        first = held[0][0]
        last = next((m for m, _ in reversed(held[1:]) if m is not None), None)
        view, points = None, None
        fview = self._fview[1] if self._fview is not None and last is not None and self._fview[0] == last.index else None
        fallback = (first.depth_prior is None and fview is None and last is not None and self.frontend is not None
                    and self.cfg.frontend.fallback_parallax_deg > 0)
        if fallback:  # no held frame met the start's parallax: the widest pair that is still usable
            best = self._fallback_view(first, [m for m, _ in held[1:] if m is not None])
            if best is not None:
                last, fview = best
        if first.depth_prior is None and fview is not None:
            points = fview.points
            view = TwoView(fview.T_world_second, None, None, fview.inliers)
            self.init_note = (f"two-view start with frame {last.index} from the frontend's tracks ({fview.inliers} "
                              f"essential-matrix inliers, {fview.parallax_deg:.1f} degrees of parallax"
                              f"{', below the usual threshold' if fallback else ''}), first frame's median tracked "
                              f"depth taken as {self.cfg.loss.first_depth_median_m} m")
            if fallback:
                log.warning("two-view start: no held frame reached %.1f degrees of parallax with frame %d; starting "
                            "from frame %d at %.1f degrees", self.cfg.frontend.init_parallax_deg, first.index,
                            last.index, fview.parallax_deg)
        elif last is not None and first.depth_prior is not None:
            median_m = self.cfg.loss.first_depth_median_m
            tracks = None
            if self.frontend is not None and self.cfg.frontend.prior_start:
                with self._frontend_timer():
                    tracks = self.frontend.two_view(first.index, last.index, median_m)
            view = None if tracks is None else two_view_from_tracks(first, last, tracks.T_world_second,
                                                                    tracks.points, tracks.inliers)
            if view is not None:
                self.scale_from = "median tracked depth"
                self.init_note = (f"two-view start with frame {last.index} from the frontend's tracks ({tracks.inliers} "
                                  f"essential-matrix inliers, {tracks.parallax_deg:.1f} degrees of parallax), both "
                                  f"priors' scale and shift fitted to its points (first: shift {view.first_scale_shift[1]:.3f})")
            else:
                reference = first_scale_shift(first, median_m) if first.normal_prior is not None else None
                view = two_view_init(first, last, median_m, reference=reference)
        if view is None:
            log.warning("two-view start failed (too little parallax or flow, or a prior fit the checks reject): scale and shift from frame %d alone",
                        first.index)
            self.init_note = "two-view start failed: first frame's shift from the normal prior"
        elif points is None and not self.init_note:
            self.init_note = (f"two-view start with frame {last.index} ({view.inliers} essential-matrix inliers): "
                              f"first prior's shift {view.first_scale_shift[1]:.3f} from flow triangulation")
        events = self._initialise(first, last if view is not None else None, view, points)
        events += self._record(first, held[0][1])  # a keyframe since it was held
        for m, f in held[1:]:
            known = self.poses[m.index] if (view is not None and m is last) else None
            if known is None and self.should_stop():
                continue  # stopping: no tracking; the frames with a pose are kept
            events += self._advance(m, f, known)
        return events

    def _fallback_view(self, first: MapFrame, held: list[MapFrame]) -> tuple[MapFrame, TwoViewTracks] | None:
        """The held frame whose tracks with `first` pass the frontend's fallback start with the
        widest median parallax (the later one on a tie), and that start; None when none does."""
        median_m = self.cfg.loss.first_depth_median_m
        with self._frontend_timer():
            views = [(m, self.frontend.two_view(first.index, m.index, median_m, fallback=True)) for m in held]
        views = [(m, v) for m, v in views if v is not None]
        return max(views, key=lambda mv: (mv[1].parallax_deg, mv[0].index)) if views else None

    def _track(self, mf: MapFrame) -> FrameTracked:
        history = [self.poses[i] for i in self.order[-2:]]
        init = self.cfg.tracking.init
        T_pred = predict_pose(history, init)
        front = self._frontend_estimate(mf.index, T_pred)
        if front is not None:  # the frontend's PnP pose seeds the photometric tracker
            T_pred = torch.as_tensor(front.T_world_cam, dtype=T_pred.dtype, device=T_pred.device)
            self._frontend_at[mf.index] = front
        elif init == "flow":
            self._attach_flows(mf)
            T_pred = self._flow_init(mf, T_pred)
        n = len(self.order) + 1
        if front is not None:
            self._scene_depth = front.median_depth
        if self.keyframe_view is not None:
            self._decide_keyframe(mf.index, T_pred, mf.timestamp, front.median_depth if front is not None else None)
        if (front is not None and self.cfg.tracking.refine == "keyframes" and not self._keyframe_due(n, mf.index)
                and not self._mapping_slot(n)):
            # Neither a keyframe nor mapped from: the frontend's pose stands.
            self.poses[mf.index] = T_pred.detach()
            self._unrefined.add(mf.index)
            return FrameTracked(mf.index, mf.timestamp, T_pred.detach().double().cpu().numpy(), math.nan, 0.0)
        res = self.tracker.track(mf, T_pred)
        reason = tracking_failure(res.T_world_cam, T_pred, res.loss, self.recent_losses, self.cfg.tracking)
        if reason is None and front is None and self.frontend is not None and len(self.keyframes) > 2:
            log.info("frame %d: the frontend has no pose (too few tracked landmarks)", mf.index)
        T = T_pred if reason else res.T_world_cam
        if reason is None and front is not None:
            T, reason = self._settle_disagreement(mf.index, res, T_pred, predict_pose(history, "constant_velocity"),
                                                  history[-1], front)
        # On a detection the frontend's pose (else the motion model's) is kept.
        if reason and front is not None:
            self._frontend_kept.add(mf.index)  # its own pose: consistent with its landmarks
        if reason and front is not None and self.cfg.tracking.rejected_keyframe == "frontend" and self._keyframe_due(n, mf.index):
            log.warning("frame %d: refinement rejected (%s): the keyframe keeps the frontend's pose", mf.index, reason)
            reason = None  # not lost: the frame stays a keyframe (its loss does not enter the running median)
        elif reason:
            self.lost_frames.append(mf.index)
            log.warning("frame %d: tracking lost (%s): using the %s pose", mf.index, reason,
                        "frontend's" if front is not None else "motion model's")
        else:
            self.recent_losses = (self.recent_losses + [res.loss])[-10:]
        self.poses[mf.index] = T.detach()
        return FrameTracked(mf.index, mf.timestamp, T.detach().double().cpu().numpy(), res.loss, res.seconds, reason)

    def _settle_disagreement(self, index: int, res, T_front: torch.Tensor, T_motion: torch.Tensor,
                             T_prev: torch.Tensor, front: FrontendPose) -> tuple[torch.Tensor, str | None]:
        """The refined pose `res` against the frontend's `T_front` (the tracker's start): when they
        disagree beyond `frontend.max_disagreement_*`, the pose the evidence favours
        (`tracking_policy.judge_disagreement`); (pose, reason the frame is not trusted or None)."""
        gap = frontend_disagreement(res.T_world_cam, T_front, T_prev, front.median_depth, self.cfg.frontend)
        if self.disagreements.observe(index, gap is not None):
            msg = f"the frontend and the map disagree on {self.disagreements.run} refined frames in a row"
            log.warning("frame %d: %s", index, msg)
            self._warnings.append(TrackingWarning(index, "disagreement", msg))
        if gap is None:
            return res.T_world_cam, None
        luv, X = self.frontend.landmark_observations(index)
        reproj = reprojection_error(res.T_world_cam.double().cpu().numpy(), X, luv, self.frontend.intr) if len(X) else 0.0
        v = judge_disagreement(res.loss, res.initial_loss, res.T_world_cam, T_front, T_motion, self.recent_losses,
                               self.cfg.tracking.loss_jump, self.cfg.frontend.evidence_ratio, reproj,
                               self.cfg.frontend.reproj_px)
        self.verdicts[v.keep] += 1
        log.info("frame %d: %s; %s: %s pose kept", index, gap, v.why, v.keep if v.keep != "lost" else "no")
        if v.keep == "map":
            self._distrusted.add(index)  # the frontend adopts the map's pose of this frame
            return res.T_world_cam, None
        return T_front, (gap if v.keep == "frontend" else v.why)

    def _refinement_failure(self, res, T_pred: torch.Tensor, T_prev: torch.Tensor,
                            front: FrontendPose | None) -> str | None:
        """Why the tracker's result `res` must not be trusted (None: it may): a tracking loss
        against the start `T_pred`, or, with the frontend's estimate `front` (whose pose `T_pred`
        is), a disagreement with it; `T_prev` is the previous frame's pose."""
        reason = tracking_failure(res.T_world_cam, T_pred, res.loss, self.recent_losses, self.cfg.tracking)
        if reason is None and front is not None:
            reason = frontend_disagreement(res.T_world_cam, T_pred, T_prev, front.median_depth, self.cfg.frontend)
        return reason

    # -- the classical frontend (no-ops without one) ------------------------------------
    @contextmanager
    def _frontend_timer(self):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.frontend_seconds += time.perf_counter() - t0

    def _frontend_estimate(self, index: int, T_guess: torch.Tensor) -> FrontendPose | None:
        """The frontend's pose of `index`, or None when it has none or its health check fails
        (`frontend/health.py`: the frame is then tracked against the map from the motion model)."""
        if self.frontend is None:
            return None
        with self._frontend_timer():
            front = self.frontend.estimate(index, T_guess.double().cpu().numpy())
            ids, uv = self.frontend.obs[index]
            luv, X = self.frontend.landmark_observations(index)
            reports = self.health.check(index, None if front is None else front.T_world_cam, ids, uv, luv, X,
                                        self.frontend.intr, None if front is None else front.median_depth)
        for r in reports:
            log.warning("%s", r)
            self._warnings.append(TrackingWarning(r.index, f"frontend {r.kind}", r.message))
        if front is not None and any(r.kind != "lost" for r in reports):
            self._distrusted.add(index)
            return None
        return front

    def _frontend_pose(self, index: int, T: torch.Tensor, trusted: bool) -> None:
        if self.frontend is not None:
            with self._frontend_timer():
                self.frontend.set_pose(index, T.double().cpu().numpy(), trusted, adopt=index in self._distrusted)

    def _flow_init(self, mf: MapFrame, T_prev: torch.Tensor) -> torch.Tensor:
        """PnP pose from the stored frames' flows to `mf` (else `T_prev`)."""
        sources = [(f, self.poses[k]) for k, f in self.frames.items() if mf.index in f.flows]
        T = pose_from_flows(sources, mf, T_prev, self.tracker.model, self.tracker.beta, self.tracker.render,
                            self.cfg.tracking.flow_points, self.tracker.gen)
        if T is None:
            log.info("frame %d: no flow PnP solution: tracking from the previous pose", mf.index)
            return T_prev
        return T

    def _skip_corrupt(self, frame: Frame) -> FrameTracked:
        """A frame with non-finite pixels: pose from the motion model, never mapped."""
        reason = "non-finite pixels in the input frame"
        log.warning("frame %d: %s: skipped (pose from the motion model)", frame.index, reason)
        self.lost_frames.append(frame.index)
        if self.order:
            T = predict_pose([self.poses[i] for i in self.order[-2:]], self.cfg.tracking.init)
        else:
            T = torch.eye(4, device=self.device)
        self.poses[frame.index] = T
        self.order.append(frame.index)
        self.timestamps[frame.index] = frame.timestamp
        return FrameTracked(frame.index, frame.timestamp, T.double().cpu().numpy(), float("nan"), 0.0, reason)

    def _progress(self, label: str) -> MappingProgress | None:
        return self.progress(label) if self.progress is not None else None

    def _landmarks(self) -> np.ndarray | None:
        """The frontend's landmarks (P, 3), world frame, or None without a frontend or landmarks."""
        if self.frontend is None or not self.frontend.landmarks:
            return None
        return np.stack(list(self.frontend.landmarks.values()))

    def _map(self, current: int, iters: int, bundle_adjust: bool = True, closing: bool = False) -> list[MapUpdated]:
        """Plan a mapping call and submit it; the calls that have finished come back as events
        (this one at once with the inline executor)."""
        window = select_window(self.keyframes, current, self.cfg.mapping, self.rng)
        anchor = self.order[0]
        ba = ba_frames(window, current, anchor) if bundle_adjust and self.cfg.mapping.ba_start < 1.0 else set()
        if self.stereo is not None:
            # Pairs posed by the frontend: consistent with each other where refined keyframes are not.
            self.stereo.update(window, self.frames, self.poses, self.keyframes, self.bound, self._landmarks(),
                               self.frontend.placed() if self.frontend is not None else None)
        mode = self.cfg.loss.slam_prior_alignment
        if mode == "map":
            for k in window:
                f = self.frames[k]
                if f.depth_scale_shift is None:
                    f.depth_scale_shift = align_prior_to_map(f, self.poses[k], *self.map_view(), self.cfg.render)
        elif mode == "flow":
            self._align_by_flow(window)
        label = f"{'closing mapping' if closing else 'mapping'} @ frame {current}"
        final = closing and not bundle_adjust  # the `final_iters` call, poses fixed
        m = self.cfg.mapping
        color_start, lr_end = (m.final_color_start, m.final_lr_end_factor) if final else (None, 1.0)
        job = MapJob(current, tuple(window), job_frames([self.frames[k] for k in window]),
                     {k: self.poses[k].clone() for k in window}, iters, frozenset(ba), label, closing,
                     color_start, lr_end)
        t0 = time.perf_counter()
        self.mapping.submit(job, self._run_job)
        self.mapping_wait_s += time.perf_counter() - t0
        return self._collect()

    def _run_job(self, job: MapJob) -> MapResult:
        """The executor's side (a worker thread in the background): touches only the mapper,
        the live map and the job."""
        stats = self.mapper.optimise(job.frames, job.poses, job.iters, ba_indices=set(job.ba),
                                     progress=self._progress(job.label), stop=self.should_stop,
                                     color_start=job.color_start, lr_end=job.lr_end)
        snap = take_snapshot(self.model, self.beta, self.map_version + 1) if self.mapping.background else None
        return MapResult(job, stats, snap)

    def _collect(self, wait: bool = False) -> list[MapUpdated]:
        """Apply the finished mapping calls: bundle-adjusted poses, iteration count, the map
        tracking reads."""
        events = []
        t0 = time.perf_counter()
        results = self.mapping.drain() if wait else self.mapping.poll()
        self.mapping_wait_s += time.perf_counter() - t0
        for r in results:
            for k in r.job.ba:
                self.poses[k] = r.job.poses[k]
            self.mapped_iters += r.stats.iters
            self.mapped_frames.update(r.job.window)
            self.map_version += 1
            if r.snapshot is not None:
                self._read_map(r.snapshot)
            s = r.stats
            events.append(MapUpdated(r.job.current, r.job.window, s.loss, s.iters, s.seconds, s.terms,
                                     background=self.mapping.background and not r.job.closing,
                                     version=self.map_version))
        return events

    def _read_map(self, snap) -> None:
        """Tracking (and `map_view`) read `snap` from now on."""
        self.tracker.model, self.tracker.beta = snap.model, snap.beta

    def measured_views(self, intr: Intrinsics) -> list[DepthView]:
        """The keyframes' measured stereo depth at their current poses, for the mesh's culling
        (`scene_mesh(measured=...)`); [] without plane-sweep stereo. Call it on the SLAM thread."""
        if self.stereo is None:
            return []
        poses = {k: self.poses[k].double().cpu().numpy() for k in self.stereo.measured if k in self.poses}
        return self.stereo.measured_views(poses, intr)

    def map_view(self) -> tuple[SceneModel, BetaField]:
        """The map as tracking reads it: the live one inline, else the last published snapshot
        (safe to render from the caller's thread while mapping runs)."""
        return self.tracker.model, self.tracker.beta

    def _align_by_flow(self, window: list[int]) -> None:
        """(w, q) of each window frame by flow triangulation with the current pose estimates
        (the widest-baseline partner it has a flow to); frames without one keep the fit."""
        for k in window:
            f = self.frames[k]
            if self.stereo is not None and k in self.stereo.fixed:
                continue  # stereo depth is in the poses' unit already: (1, 0)
            wq = align_to_widest_partner(f, self.frames, self.poses)
            f.depth_scale_shift = wq if wq is not None else f.depth_scale_shift

    def _store(self, mf: MapFrame) -> None:
        """Keep keyframes and the latest frame; drop the previous non-keyframe."""
        self.frames[mf.index] = mf
        for k in list(self.frames):
            if k != mf.index and k not in self.keyframes and k != self.order[0]:
                del self.frames[k]
        for f in self.frames.values():  # flows to dropped frames would pile up in keyframes
            # (not to held frames the start replays next: their tracking starts from these flows)
            for j in [j for j in f.flows if j not in self.frames and j not in self._replay]:
                del f.flows[j]


    def _cap_keyframes(self) -> None:
        """Bounded memory: keyframes older than the newest `full_res_keyframes` at half resolution."""
        cap = self.cfg.mapping.full_res_keyframes
        if cap <= 0:
            return
        for k in self.keyframes[:-cap]:
            if k != self.order[0] and k in self.frames and k not in self._halved:
                self.frames[k] = self.frames[k].halved()
                self._halved.add(k)
                for f in self.frames.values():  # flows into it are in full-resolution pixels
                    f.flows.pop(k, None)

    # -- results ---------------------------------------------------------------------
    def health_summary(self) -> dict:
        """What went wrong in tracking, for `summary.json`: the frontend's health reports by kind
        (and the first 100), the disagreements settled by evidence, the frames the start passed
        over, the disagreement streaks."""
        return {"frontend_reports": self.health.counts(),
                "frontend_report_lines": [str(r) for r in self.health.reports[:100]],
                "disagreements_kept": dict(self.verdicts),
                "unposed_before_start": list(self.unposed),
                "disagreement_streaks": [{"first_frame": a, "frames": n} for a, n in self.disagreements.streaks],
                "keyframe_reasons": ({str(k): r for k, r in self.keyframe_view.reasons.items()}
                                     if self.keyframe_view is not None else "every mapping.keyframe_every frames")}

    def trajectory(self) -> tuple[list[float], list[np.ndarray]]:
        """(timestamps, T_world_cam float64) of every frame so far, in input order: the frames that
        hold the frontend's pose moved with the map's corrections of the keyframes around them
        (`pose_corrections.py`; the poses tracking goes on from are not changed)."""
        anchors = (self.mapped_frames | set(self.keyframes)) & set(self.poses)
        # In the poses' float32, as tracking started from them (an unmoved keyframe: no correction).
        frontend = {k: torch.as_tensor(f.T_world_cam, dtype=self.poses[k].dtype, device=self.poses[k].device)
                    for k, f in self._frontend_at.items() if k in self.poses}
        poses = spread_corrections(self.order, self.poses, frontend, anchors, self._unrefined)
        return [self.timestamps[i] for i in self.order], [poses[i].double().cpu().numpy() for i in self.order]
