"""How the SLAM starts, as a state machine over the first frames.

EMPTY (no map, nothing held) -> HOLDING: the first frame is held for a two-view start
  (`mapping.init = 'two_view'`, or 'auto' without a depth prior): with a depth prior until
  `init_frames` frames follow it; without one (the frontend's start) until the frontend sees
  enough parallax with the first, at most `init_max_frames`. Without a depth prior the first view
  slides forward to the oldest held frame that still shares enough tracks with the newest.
EMPTY -> RUNNING: the first frame alone starts the map (`first_frame`, or 'auto' with a depth prior).
HOLDING -> RUNNING: the start's second view is chosen (the frontend's tracks, else flow
  triangulation of the priors, else the first frame alone) and the held frames are replayed.
A corrupt frame in EMPTY starts nothing. `offer` returns what the caller does next."""
from __future__ import annotations

import enum
import itertools
import logging
from dataclasses import dataclass, field

import numpy as np

from nicer_stream.config import SlamConfig
from nicer_stream.frontend.frontend import TwoViewTracks
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.slam.events import Event, KeyframeAdded
from nicer_stream.slam.first_map import first_scale_shift
from nicer_stream.slam.frontend_link import FrontendLink
from nicer_stream.slam.state import SlamState
from nicer_stream.slam.two_view import TwoView, two_view_from_tracks, two_view_init
from nicer_stream.types import Frame

log = logging.getLogger(__name__)


class StartPhase(enum.Enum):
    EMPTY = "no map, nothing held"
    HOLDING = "frames held for the two-view start"
    RUNNING = "started: frames go through tracking"


@dataclass
class StartPlan:
    """How the map starts: `first` at the identity and, with a two-view start, `second` at `view`'s
    pose (None: the first frame alone); `points` (M, 3) world: the frontend's triangulated tracks,
    which set the bound without a depth prior; `rest`: the held frames after the first, in order."""

    first: MapFrame
    first_raw: Frame
    second: MapFrame | None = None
    view: TwoView | None = None
    points: np.ndarray | None = None
    rest: list[tuple[MapFrame | None, Frame]] = field(default_factory=list)

    @property
    def window(self) -> list[MapFrame]:
        return [self.first] + ([self.second] if self.second is not None else [])


class Startup:
    def __init__(self, cfg: SlamConfig, state: SlamState, front: FrontendLink) -> None:
        self.cfg, self.state, self.front = cfg, state, front
        self.phase = StartPhase.EMPTY
        self.held: list[tuple[MapFrame | None, Frame]] = []  # (None: a corrupt frame)
        self.unposed: list[int] = []  # frames the first view slid past: no pose
        self.init_note = ""  # how the start went, for `summary.json`
        self.scale_from = "depth-prior median"  # what `first_depth_median_m` sets: the first frame's ...
        self._fview: tuple[int, TwoViewTracks | None] | None = None  # the frontend's start with frame i (cached)

    @property
    def pending(self) -> list[MapFrame]:
        """The held frames (not the corrupt ones)."""
        return [m for m, _ in self.held if m is not None]

    def offer(self, mf: MapFrame | None, frame: Frame) -> list[Event] | StartPlan | None:
        """The next frame before the start (`mf` None: corrupt): the events of holding it, or the
        plan to start now (this frame included), or None (a corrupt frame: nothing to start from)."""
        if self.phase is StartPhase.HOLDING:
            self._slide(mf)
        if self._waits(mf):
            return self._hold(mf, frame)
        if self.phase is StartPhase.HOLDING:
            return self.begin(mf, frame)
        if mf is None:
            return None
        self.phase = StartPhase.RUNNING
        return StartPlan(mf, frame)

    def _hold(self, mf: MapFrame | None, frame: Frame) -> list[Event]:
        self.held.append((mf, frame))
        if len(self.held) > 1:
            return []
        # The first frame is a keyframe from the start: priors flow from it to the next ones.
        self.phase = StartPhase.HOLDING
        self.state.keyframes.append(frame.index)
        self.front.pin({frame.index})
        return [KeyframeAdded(frame.index)]

    def _waits(self, mf: MapFrame | None) -> bool:
        """Whether to hold `mf` for the two-view start."""
        init = self.cfg.mapping.init
        if init == "first_frame":
            return False
        if not self.held:
            if mf is None or (init == "auto" and mf.depth_prior is not None):
                return False  # 'auto' with a depth prior: the first frame's start
            return mf.depth_prior is not None or self.front.frontend is not None
        if self.held[0][0].depth_prior is None:
            if mf is not None and self._frontend_view(mf.index) is not None:
                return False
            return len(self.held) < self.cfg.mapping.init_max_frames
        return len(self.held) < self.cfg.mapping.init_frames

    def _frontend_view(self, index: int) -> TwoViewTracks | None:
        """The frontend's two-view geometry between the first held frame and `index` (cached)."""
        if self.front.frontend is None or not self.held:
            return None
        if self._fview is None or self._fview[0] != index:
            self._fview = (index, self.front.two_view(self.held[0][0].index, index, self.cfg.loss.first_depth_median_m))
        return self._fview[1]

    def _slide(self, mf: MapFrame | None) -> None:
        """Without a depth prior the start needs tracks the first held view shares with a later
        one: the first view moves to the oldest held frame that still shares enough with `mf`
        (`ClassicalFrontend.stale_first_views`; never onto or past a corrupt frame); the frames it
        passes get no pose."""
        frontend, first = self.front.frontend, self.held[0][0]
        if frontend is None or mf is None or first is None or first.depth_prior is not None:
            return
        held = [m for m, _ in itertools.takewhile(lambda h: h[0] is not None, self.held)]
        drop = frontend.stale_first_views([m.index for m in held], mf.index)
        if not drop:
            return
        passed = [m.index for m, _ in self.held[:drop] if m is not None]
        self.unposed += passed
        self.held = self.held[drop:]
        first = self.held[0][0].index
        self.state.keyframes = [first]
        self.front.pin({first})
        self._fview = None
        log.info("two-view start: frame %d shares too few tracks with frame %d: the start moves to frame %d "
                 "(frames %d-%d get no pose)", passed[0], mf.index, first, passed[0], passed[-1])

    def begin(self, mf: MapFrame | None, frame: Frame | None) -> StartPlan:
        """The two-view start from the held frames (+ `mf`, the newest, when given): the second
        view, or the first frame alone when no pair passes."""
        held = self.held + ([(mf, frame)] if frame is not None else [])
        self.front.pin(set())
        self.held, self.phase = [], StartPhase.RUNNING
        self.state.replay = {m.index for m, _ in held[1:] if m is not None}
        first, later = held[0][0], [m for m, _ in held[1:] if m is not None]
        last = later[-1] if later else None
        view, points = None, None
        if first.depth_prior is None:
            last, view, points = self._from_tracks(first, last, later)
        elif last is not None:
            view = self._from_priors(first, last)
        if view is None:
            log.warning("two-view start failed (too little parallax or flow, or a prior fit the checks reject): "
                        "scale and shift from frame %d alone", first.index)
            self.init_note = "two-view start failed: first frame's shift from the normal prior"
        elif points is None and not self.init_note:
            self.init_note = (f"two-view start with frame {last.index} ({view.inliers} essential-matrix inliers): "
                              f"first prior's shift {view.first_scale_shift[1]:.3f} from flow triangulation")
        return StartPlan(first, held[0][1], last if view is not None else None, view, points, held[1:])

    def _from_tracks(self, first: MapFrame, last: MapFrame | None, later: list[MapFrame]):
        """Without a depth prior: the frontend's start with the newest held frame, else (with
        `fallback_parallax_deg`) the widest pair the fallback accepts; (second, view, points)."""
        fview = self._fview[1] if self._fview is not None and last is not None and self._fview[0] == last.index else None
        fallback = (fview is None and last is not None and self.front.frontend is not None
                    and self.cfg.frontend.fallback_parallax_deg > 0)
        if fallback:  # no held frame met the start's parallax: the widest pair that is still usable
            best = self._fallback_view(first, later)
            if best is not None:
                last, fview = best
        if fview is None:
            return last, None, None
        self.init_note = (f"two-view start with frame {last.index} from the frontend's tracks ({fview.inliers} "
                          f"essential-matrix inliers, {fview.parallax_deg:.1f} degrees of parallax"
                          f"{', below the usual threshold' if fallback else ''}), first frame's median tracked "
                          f"depth taken as {self.cfg.loss.first_depth_median_m} m")
        if fallback:
            log.warning("two-view start: no held frame reached %.1f degrees of parallax with frame %d; starting "
                        "from frame %d at %.1f degrees", self.cfg.frontend.init_parallax_deg, first.index,
                        last.index, fview.parallax_deg)
        return last, TwoView(fview.T_world_second, None, None, fview.inliers), fview.points

    def _fallback_view(self, first: MapFrame, held: list[MapFrame]) -> tuple[MapFrame, TwoViewTracks] | None:
        """The held frame whose tracks with `first` pass the frontend's fallback start with the
        widest median parallax (the later one on a tie), and that start; None when none does."""
        median_m = self.cfg.loss.first_depth_median_m
        with self.front.timer():
            views = [(m, self.front.frontend.two_view(first.index, m.index, median_m, fallback=True)) for m in held]
        views = [(m, v) for m, v in views if v is not None]
        return max(views, key=lambda mv: (mv[1].parallax_deg, mv[0].index)) if views else None

    def _from_priors(self, first: MapFrame, last: MapFrame) -> TwoView | None:
        """With depth priors: both priors' (w, q) fitted to the frontend's triangulated tracks
        (`frontend.prior_start`), else to flow triangulation between `first` and `last`."""
        median_m = self.cfg.loss.first_depth_median_m
        tracks = self.front.two_view(first.index, last.index, median_m) if self.cfg.frontend.prior_start else None
        view = None if tracks is None else two_view_from_tracks(first, last, tracks.T_world_second,
                                                                tracks.points, tracks.inliers)
        if view is None:
            reference = first_scale_shift(first, median_m) if first.normal_prior is not None else None
            return two_view_init(first, last, median_m, reference=reference)
        self.scale_from = "median tracked depth"
        self.init_note = (f"two-view start with frame {last.index} from the frontend's tracks ({tracks.inliers} "
                          f"essential-matrix inliers, {tracks.parallax_deg:.1f} degrees of parallax), both "
                          f"priors' scale and shift fitted to its points (first: shift {view.first_scale_shift[1]:.3f})")
        return view
