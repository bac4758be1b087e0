"""Typed events emitted by the SLAM system (consumed by sinks, progress, the CLI)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class FrameTracked:
    """A frame's estimated T_world_cam (4, 4) float64; `lost` names a tracking failure (pose then
    comes from the motion model)."""

    index: int
    timestamp: float
    T_world_cam: np.ndarray
    loss: float
    seconds: float
    lost: str | None = None


@dataclass(frozen=True)
class KeyframeAdded:
    index: int


@dataclass(frozen=True)
class MapUpdated:
    """A mapping call finished over `window` frame indices (`iters` done: fewer after a stop)."""

    index: int
    window: tuple[int, ...]
    loss: float
    iters: int
    seconds: float
    terms: dict[str, float] = field(default_factory=dict)
    """The last iteration's loss terms (unweighted), by name."""
    background: bool = False
    """Ran on the mapping worker while tracking went on (its seconds overlap the frames')."""
    version: int = 0
    """The map version it produced (mapping calls applied so far)."""


@dataclass(frozen=True)
class TrackingWarning:
    """Something about tracking a user should see at frame `index`: `kind` is a frontend health
    report's kind (lost, reprojection, frozen, scale) or 'disagreement' (a streak of frames where
    the frontend and the map disagree); `message` is one line."""

    index: int
    kind: str
    message: str


Event = FrameTracked | KeyframeAdded | MapUpdated | TrackingWarning
