"""The mapping calls: each planned in the caller's thread (its window, the frames bundle adjustment
may move, the keyframes' stereo priors and the priors' alignment), run by the executor as a job
(`map_jobs.py`), and its result applied back in the caller's thread: the adjusted poses, the
iteration count, the map version tracking reads. A call the schedule asks for while the worker
is busy starts at the next trusted frame."""
from __future__ import annotations

import random
import time
from typing import Callable

from nicer_stream.config import SlamConfig
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.prior_alignment import align_prior_to_map, align_to_widest_partner
from nicer_stream.model.scene import SceneModel
from nicer_stream.priors.keyframe_stereo import StereoPriors
from nicer_stream.render.beta import BetaField
from nicer_stream.slam.events import MapUpdated
from nicer_stream.slam.frontend_link import FrontendLink
from nicer_stream.slam.map_jobs import InlineMapping, MapJob, MappingExecutor, MapResult, MapSnapshot, job_frames, take_snapshot
from nicer_stream.slam.state import SlamState
from nicer_stream.slam.window import ba_frames, select_window

# (iteration, iterations, loss) after each mapping iteration (Mapper.optimise's `progress`).
MappingProgress = Callable[[int, int, float], None]


class MapCalls:
    def __init__(self, cfg: SlamConfig, state: SlamState, front: FrontendLink, stereo: StereoPriors | None,
                 executor: MappingExecutor | None, progress: Callable[[str], MappingProgress | None] | None,
                 should_stop: Callable[[], bool] | None) -> None:
        self.cfg, self.state, self.front, self.stereo = cfg, state, front, stereo
        self.executor = executor or InlineMapping()
        self.progress = progress
        # Polled by mapping iterations (and between the held frames of the two-view start): a stop
        # request ends them early (the caller then writes what exists).
        self.should_stop = should_stop or (lambda: False)
        self.rng = random.Random(cfg.seed)
        self.version = 0  # calls applied; tracking reads this version of the map
        self.iters = 0  # iterations done (0: the scene is still the initial sphere)
        self.wait_s = 0.0  # the caller's seconds in mapping: inline calls and waits for the worker
        self.due = False  # a call the schedule asked for while the worker was busy

    def first(self, window: list[MapFrame], fixed_scale_shift: tuple[float, float] | None) -> MapUpdated:
        """The start's call over its one or two frames, in the caller's thread: one long call from
        the sphere, like `map`, the colour grids joining early."""
        s, cfg = self.state, self.cfg
        if self.stereo is not None:
            idx = [f.index for f in window]
            self.stereo.update(idx, {f.index: f for f in window}, s.poses, idx, s.bound, self.front.landmarks())
        label = f"first mapping (frame{'s' if len(window) > 1 else ''} {','.join(str(f.index) for f in window)})"
        stats = s.mapper.optimise(window, s.poses, cfg.mapping.first_iters, fixed_scale_shift=fixed_scale_shift,
                                  progress=self._progress(label), color_start=cfg.mapping.batch_color_start,
                                  stop=self.should_stop)
        self.iters += stats.iters
        s.mapped_frames.update(f.index for f in window)
        self.wait_s += stats.seconds
        self.version += 1
        if self.executor.background:  # the worker will change the live map: tracking reads a copy
            self.read(take_snapshot(s.model, s.beta, self.version))
        return MapUpdated(window[0].index, tuple(f.index for f in window), stats.loss, stats.iters, stats.seconds,
                          stats.terms, version=self.version)

    def at(self, current: int) -> list[MapUpdated]:
        """The schedule's call at trusted frame `current`: now, or at the next frame while the
        worker is still on the last call."""
        events = self.collect()  # a call that has just finished frees the worker
        if self.executor.busy():
            self.due = True
            return events
        self.due = False
        return events + self.submit(current, self.cfg.mapping.iters)

    def close(self) -> list[MapUpdated]:
        """The run's closing call over the latest frame's window: `final_iters` with the poses
        fixed when set, else `iters` if it was not just mapped."""
        s, m = self.state, self.cfg.mapping
        if m.final_iters is not None:
            return self.submit(s.order[-1], m.final_iters, bundle_adjust=False, closing=True)
        if (len(s.order) - 1) % m.every != 0 or self.due:
            return self.submit(s.order[-1], m.iters, closing=True)
        return []

    def submit(self, current: int, iters: int, bundle_adjust: bool = True, closing: bool = False) -> list[MapUpdated]:
        """Plan a call and submit it; the calls that have finished come back as events (this one
        at once with the inline executor)."""
        job = self._plan(current, iters, bundle_adjust, closing)
        t0 = time.perf_counter()
        self.executor.submit(job, self.run)
        self.wait_s += time.perf_counter() - t0
        return self.collect()

    def _plan(self, current: int, iters: int, bundle_adjust: bool, closing: bool) -> MapJob:
        s, m = self.state, self.cfg.mapping
        window = select_window(s.keyframes, current, m, self.rng)
        ba = ba_frames(window, current, s.order[0]) if bundle_adjust and m.ba_start < 1.0 else set()
        if self.stereo is not None:
            # Pairs posed by the frontend: consistent with each other where refined keyframes are not.
            self.stereo.update(window, s.frames, s.poses, s.keyframes, s.bound, self.front.landmarks(),
                               self.front.placed())
        self._align_priors(window)
        label = f"{'closing mapping' if closing else 'mapping'} @ frame {current}"
        final = closing and not bundle_adjust  # the `final_iters` call, poses fixed
        color_start, lr_end = (m.final_color_start, m.final_lr_end_factor) if final else (None, 1.0)
        return MapJob(current, tuple(window), job_frames([s.frames[k] for k in window]),
                      {k: s.poses[k].clone() for k in window}, iters, frozenset(ba), label, closing,
                      color_start, lr_end)

    def _align_priors(self, window: list[int]) -> None:
        """(w, q) of the window frames' depth priors (`loss.slam_prior_alignment`): 'map' fits a
        frame without one to the map once; 'flow' triangulates each frame with the widest-baseline
        partner it has a flow to at the current poses (frames without one keep the fit)."""
        s, mode = self.state, self.cfg.loss.slam_prior_alignment
        for k in window:
            f = s.frames[k]
            if mode == "map" and f.depth_scale_shift is None:
                f.depth_scale_shift = align_prior_to_map(f, s.poses[k], *self.view(), self.cfg.render)
            elif mode == "flow" and not (self.stereo is not None and k in self.stereo.fixed):
                # (stereo depth is in the poses' unit already: (1, 0))
                wq = align_to_widest_partner(f, s.frames, s.poses)
                f.depth_scale_shift = wq if wq is not None else f.depth_scale_shift

    def run(self, job: MapJob) -> MapResult:
        """The executor's side (a worker thread in the background): touches only the mapper,
        the live map and the job."""
        s = self.state
        stats = s.mapper.optimise(job.frames, job.poses, job.iters, ba_indices=set(job.ba),
                                  progress=self._progress(job.label), stop=self.should_stop,
                                  color_start=job.color_start, lr_end=job.lr_end)
        snap = take_snapshot(s.model, s.beta, self.version + 1) if self.executor.background else None
        return MapResult(job, stats, snap)

    def collect(self, wait: bool = False) -> list[MapUpdated]:
        """Apply the finished calls: bundle-adjusted poses, iteration count, the map tracking reads."""
        s, events = self.state, []
        t0 = time.perf_counter()
        results = self.executor.drain() if wait else self.executor.poll()
        self.wait_s += time.perf_counter() - t0
        for r in results:
            for k in r.job.ba:
                s.poses[k] = r.job.poses[k]
            self.iters += r.stats.iters
            s.mapped_frames.update(r.job.window)
            self.version += 1
            if r.snapshot is not None:
                self.read(r.snapshot)
            st = r.stats
            events.append(MapUpdated(r.job.current, r.job.window, st.loss, st.iters, st.seconds, st.terms,
                                     background=self.executor.background and not r.job.closing,
                                     version=self.version))
        return events

    def read(self, snap: MapSnapshot) -> None:
        """Tracking (and `view`) read `snap` from now on."""
        self.state.tracker.model, self.state.tracker.beta = snap.model, snap.beta

    def view(self) -> tuple[SceneModel, BetaField]:
        """The map as tracking reads it: the live one inline, else the last published snapshot."""
        return self.state.tracker.model, self.state.tracker.beta

    def _progress(self, label: str) -> MappingProgress | None:
        return self.progress(label) if self.progress is not None else None
