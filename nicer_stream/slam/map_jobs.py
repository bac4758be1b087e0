"""Mapping calls as jobs: `SlamSystem` plans a job and applies its result in the caller's
thread; an executor runs it. `InlineMapping` runs it at once (the synchronous schedule,
deterministic under a seed); the runtime's `MappingThread` runs it on a worker while tracking
goes on against the last published `MapSnapshot` (slam/ itself starts no threads).
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from typing import Callable, Protocol

import torch

from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import MappingStats
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField


@dataclass
class MapJob:
    """One mapping call over `window` (frame indices) ending at frame `current`."""

    current: int
    window: tuple[int, ...]
    frames: list[MapFrame]
    """The window's frames as shallow copies with their own `flows` dicts: tracking adds flows
    to the stored frames while the job runs."""
    poses: dict[int, torch.Tensor]
    """T_world_cam (4, 4) of the window's frames at planning time; bundle adjustment writes the
    refined poses of `ba` into this dict (never into the system's)."""
    iters: int
    ba: frozenset[int]
    label: str
    closing: bool = False
    """The run's last call: the caller waits for it (an executor may give it every core)."""
    color_start: float | None = None
    """Fraction of `iters` after which the colour grids join; None: the mapper's default."""
    lr_end: float = 1.0
    """The scene's learning rates at the call's end as a fraction of their start."""


@dataclass(frozen=True)
class MapSnapshot:
    """A frozen copy of the map that tracking reads while mapping changes the live one."""

    version: int
    model: SceneModel
    beta: BetaField


@dataclass
class MapResult:
    job: MapJob
    stats: MappingStats
    snapshot: MapSnapshot | None = None
    """The map after the job (background executors), else None: tracking reads the live map."""


def job_frames(frames: list[MapFrame]) -> list[MapFrame]:
    """Shallow copies whose `flows` dicts are their own (tensors shared, never modified in place)."""
    return [dataclasses.replace(f, flows=dict(f.flows)) for f in frames]


def take_snapshot(model: SceneModel, beta: BetaField, version: int) -> MapSnapshot:
    """Deep copies of the scene and the beta field without gradients (a few MB at `fast` sizes)."""
    with torch.no_grad():
        m, b = copy.deepcopy(model), copy.deepcopy(beta)
    for p in list(m.parameters()) + list(b.parameters()):
        p.requires_grad_(False)
    return MapSnapshot(version, m, b)


class MappingExecutor(Protocol):
    background: bool
    """True: jobs run while the caller goes on (results carry snapshots)."""

    def submit(self, job: MapJob, run: Callable[[MapJob], MapResult]) -> None: ...
    def busy(self) -> bool: ...
    def poll(self) -> list[MapResult]:
        """Finished results, without waiting (re-raises a job's exception)."""
    def drain(self) -> list[MapResult]:
        """Every result, waiting for the job in hand."""


class InlineMapping:
    """Runs each job as it is submitted, in the caller's thread."""

    background = False

    def __init__(self) -> None:
        self._done: list[MapResult] = []

    def submit(self, job: MapJob, run: Callable[[MapJob], MapResult]) -> None:
        self._done.append(run(job))

    def busy(self) -> bool:
        return False

    def poll(self) -> list[MapResult]:
        done, self._done = self._done, []
        return done

    def drain(self) -> list[MapResult]:
        return self.poll()
