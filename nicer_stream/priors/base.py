"""Prior provider interfaces and the PriorEngine that combines them.

Conventions (docs/conventions.md): depth priors are relative (unknown scale
and shift), normals are unit vectors in the camera frame (OpenCV axes x right,
y down, z forward) facing the camera, flow is (du, dv) pixels src -> dst.
"""
from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from nicer_stream.types import FlowPrior, Frame, Priors


@dataclass(frozen=True)
class DepthNormal:
    """Per-frame monocular prediction.

    depth: (H, W) float32 relative depth (unknown scale/shift, larger = farther), or None.
    normal: (H, W, 3) float32 unit camera-frame normals facing the camera, or None.
    """

    depth: np.ndarray | None
    normal: np.ndarray | None


class DepthNormalProvider:
    """Predicts a DepthNormal for a frame. `name` labels the outputs (e.g. 'oracle')."""

    name: str = "abstract"
    description: str | None = None
    """One line for outputs: what the provider is (and how honest), when it is worth saying."""
    auto_reason: str | None = None
    """Set when `--priors auto` chose this provider: why."""

    def predict(self, frame: Frame) -> DepthNormal:  # pragma: no cover - abstract
        raise NotImplementedError


class FlowProvider:
    """Optical flow between two frames. `name` labels the outputs. A provider overrides `flow`,
    or `flow_both` when it gets both directions at once (DIS, RAFT).

    `active` is False for the `none` provider: the engine then computes no flow.
    """

    name: str = "abstract"
    active: bool = True

    def flow(self, src: Frame, dst: Frame) -> FlowPrior:
        """Flow src -> dst."""
        return self.flow_both(src, dst)[0]

    def has(self, src: Frame, dst: Frame) -> bool:
        """Whether this provider can give the flow src -> dst (a cache holds only some pairs)."""
        return True

    def flow_both(self, a: Frame, b: Frame) -> tuple[FlowPrior, FlowPrior]:
        """(flow a -> b, flow b -> a). Providers that get both at once (DIS) override this."""
        return self.flow(a, b), self.flow(b, a)


class NoDepthNormal(DepthNormalProvider):
    """The `none` provider: no depth, no normals."""

    name = "none"

    def predict(self, frame: Frame) -> DepthNormal:
        return DepthNormal(depth=None, normal=None)


class NoFlow(FlowProvider):
    """The `none` flow provider: zero flow, nothing valid (the engine skips it)."""

    name = "none"
    active = False

    def flow(self, src: Frame, dst: Frame) -> FlowPrior:
        h, w = src.height, src.width
        return FlowPrior(src.index, dst.index, np.zeros((h, w, 2), np.float32), np.zeros((h, w), bool))


class PriorEngine:
    """Gives `Priors` for frames from a depth/normal provider and a flow provider.

    Flows are cached in memory per (src_index, dst_index) pair, at most
    `max_cached_flows` of them (least recently used dropped first) so that a
    long stream does not grow without bound.
    """

    def __init__(self, depth_normal: DepthNormalProvider, flow: FlowProvider, max_cached_flows: int = 32) -> None:
        self.depth_normal = depth_normal
        self.flow_provider = flow
        self.max_cached_flows = max_cached_flows
        self._flows: OrderedDict[tuple[int, int], FlowPrior] = OrderedDict()

    @property
    def label(self) -> str:
        """'DEPTHNORMAL+FLOW' provider names, written into Priors.provider and outputs."""
        return f"{self.depth_normal.name}+{self.flow_provider.name}"

    def flow(self, src: Frame, dst: Frame) -> FlowPrior | None:
        """Flow src -> dst (cached), or None with the `none` flow provider."""
        if not self.flow_provider.active or not self.flow_provider.has(src, dst):
            return None
        key = (src.index, dst.index)
        hit = self._flows.get(key)
        if hit is not None:
            self._flows.move_to_end(key)
            return hit
        fw, bw = self.flow_provider.flow_both(src, dst)
        self._put((dst.index, src.index), bw)
        self._put(key, fw)
        return fw

    def priors(self, frame: Frame, others: Iterable[Frame] = ()) -> Priors:
        """Depth/normal of `frame` and its flows to each of `others`."""
        dn = self.depth_normal.predict(frame)
        flows = self.flows((frame, o) for o in others)
        return Priors(frame_index=frame.index, provider=self.label, depth=dn.depth, normal=dn.normal, flows=flows)

    def flows(self, pairs: Iterable[tuple[Frame, Frame]]) -> list[FlowPrior]:
        """The flow src -> dst of each (src, dst) pair, in order, leaving out those it has none of."""
        return [f for f in (self.flow(src, dst) for src, dst in pairs) if f is not None]

    def _put(self, key: tuple[int, int], value: FlowPrior) -> None:
        self._flows[key] = value
        self._flows.move_to_end(key)
        while len(self._flows) > self.max_cached_flows:
            self._flows.popitem(last=False)
