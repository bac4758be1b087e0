"""Frame selection for mapping (Sec. 3.4)."""
from __future__ import annotations

import random

from nicer_stream.config import MappingConfig


def select_window(keyframes: list[int], current: int, cfg: MappingConfig, rng: random.Random) -> list[int]:
    """K frames: `window_random` random keyframes, `window_recent` random ones among the
    latest `recent_pool` keyframes, and the current frame; duplicates dropped, sorted."""
    pool = [k for k in keyframes if k != current]
    recent = pool[-cfg.recent_pool:]
    chosen = set(rng.sample(recent, min(cfg.window_recent, len(recent))))
    rest = [k for k in pool if k not in chosen]
    chosen |= set(rng.sample(rest, min(cfg.window_random, len(rest))))
    return sorted(chosen | {current})


def ba_frames(window: list[int], current: int, anchor: int) -> set[int]:
    """The half of the window nearest to the current frame (by index), minus the anchor
    frame that fixes the gauge (its pose is the world frame)."""
    near = sorted(window, key=lambda k: abs(current - k))[: max(1, len(window) // 2)]
    return {k for k in near if k != anchor}
