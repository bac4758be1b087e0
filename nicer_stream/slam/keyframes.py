"""Which frames become keyframes and which start mapping calls, and how the frames are stored.

Keyframes: every `keyframe_every`-th frame in input order, or (`keyframes = 'view'`) each frame
whose view has changed enough since the last keyframe (`view_change.py`). A frame whose pose is
not trusted never becomes one; with keyframe-only refinement its slot passes to the next frame,
else the map would go a whole interval without a keyframe. Mapping calls: every `mapping.every`
frames, or at each view keyframe. Memory: the stored frames are the keyframes, the first frame
and the latest one; keyframes older than the newest `full_res_keyframes` are kept at half
resolution."""
from __future__ import annotations

import logging

import numpy as np
import torch

from nicer_stream.config import SlamConfig
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.slam.events import Event, KeyframeAdded
from nicer_stream.slam.frontend_link import FrontendLink
from nicer_stream.slam.state import SlamState
from nicer_stream.slam.view_change import KeyframeRule, KeyframeSelector

log = logging.getLogger(__name__)


class KeyframePolicy:
    def __init__(self, cfg: SlamConfig, state: SlamState, front: FrontendLink) -> None:
        self.cfg, self.state, self.front = cfg, state, front
        m = cfg.mapping
        self.view = KeyframeSelector(KeyframeRule(
            m.keyframe_min_overlap, m.keyframe_max_baseline, m.keyframe_max_rotation_deg,
            m.keyframe_max_gap_s)) if m.keyframes == "view" else None
        self.decided: dict[int, str | None] = {}  # view keyframes: decided, not yet taken
        self.owed = False  # a keyframe slot's frame failed its check (`tracking.refine`)
        self.halved: set[int] = set()  # keyframes kept at half resolution

    def slot(self, n: int) -> bool:
        """True when the n-th frame in order (1-based) is due to become a keyframe by count."""
        return n % self.cfg.mapping.keyframe_every == 1 or self.cfg.mapping.keyframe_every == 1

    def due(self, n: int, index: int) -> bool:
        """True when frame `index`, the n-th in order, is a keyframe slot (or, with view keyframes,
        its view has changed) or takes a failed slot's place."""
        if self.view is not None:
            return self.decided.get(index) is not None or self.owed
        return self.slot(n) or self.owed

    def mapping_slot(self, n: int) -> bool:
        """True when the n-th frame in order (1-based) is due to start a mapping call by the
        frame count (view keyframes: never; each keyframe starts one)."""
        return self.view is None and n > 1 and (n - 1) % self.cfg.mapping.every == 0

    def decide(self, index: int, T: torch.Tensor | np.ndarray, timestamp: float, depth: float | None) -> None:
        """View keyframes: whether frame `index` (its pose estimate T, the scene's median depth or
        None) has seen enough change since the last keyframe; the reason is kept."""
        if self.view is None:
            return
        depth = depth or self.front.scene_depth
        T = T.double().cpu().numpy() if isinstance(T, torch.Tensor) else T
        self.decided[index] = self.view.decide(T, timestamp, depth, self.front.intr)

    def schedule(self, index: int, timestamp: float, trusted: bool) -> tuple[bool, bool]:
        """(a keyframe is due, a mapping call is due) at frame `index`, just booked in order, whose
        pose is `trusted` or not."""
        if self.view is not None and index not in self.decided:  # not tracked (the start, a replay)
            self.decide(index, self.state.poses[index], timestamp, None)
        n = len(self.state.order)
        is_kf = self.due(n, index)
        self.owed = is_kf and not trusted and self.cfg.tracking.refine == "keyframes"
        return is_kf, self.mapping_slot(n) or (self.view is not None and is_kf and n > 1)

    def add(self, index: int, timestamp: float) -> list[Event]:
        """Frame `index` becomes a keyframe (the first frame was made one when it was held)."""
        events: list[Event] = []
        if index not in self.state.keyframes:
            self.state.keyframes.append(index)
            events.append(KeyframeAdded(index))
            self._cap()
        self._taken(index, timestamp)
        return events

    def _taken(self, index: int, timestamp: float) -> None:
        if self.view is None or index in self.view.reasons:
            return
        reason = self.decided.get(index) or "a failed keyframe's place"
        log.info("frame %d: keyframe (%s)", index, reason)
        self.view.taken(index, self.front.view_landmarks(index), self.state.poses[index].double().cpu().numpy(),
                        timestamp, reason)
        for k in [k for k in self.decided if k <= index]:
            del self.decided[k]  # decided: bounded memory

    def store(self, mf: MapFrame) -> None:
        """Keep keyframes, the first and the latest frame; drop the previous non-keyframe."""
        s = self.state
        s.frames[mf.index] = mf
        for k in list(s.frames):
            if k != mf.index and k not in s.keyframes and k != s.order[0]:
                del s.frames[k]
        for f in s.frames.values():  # flows to dropped frames would pile up in keyframes
            # (not to held frames the start replays next: their tracking starts from these flows)
            for j in [j for j in f.flows if j not in s.frames and j not in s.replay]:
                del f.flows[j]

    def _cap(self) -> None:
        """Bounded memory: keyframes older than the newest `full_res_keyframes` at half resolution."""
        cap, s = self.cfg.mapping.full_res_keyframes, self.state
        if cap <= 0:
            return
        for k in s.keyframes[:-cap]:
            if k != s.order[0] and k in s.frames and k not in self.halved:
                s.frames[k] = s.frames[k].halved()
                self.halved.add(k)
                for f in s.frames.values():  # flows into it are in full-resolution pixels
                    f.flows.pop(k, None)

    def reasons(self) -> dict[str, str] | str:
        """Why each keyframe was taken, for `summary.json`."""
        if self.view is None:
            return "every mapping.keyframe_every frames"
        return {str(k): r for k, r in self.view.reasons.items()}
