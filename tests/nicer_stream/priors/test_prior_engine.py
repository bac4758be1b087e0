"""PriorEngine: combines providers, caches flows per (src, dst) pair with a bound."""
from __future__ import annotations

import numpy as np

from nicer_stream.priors.base import DepthNormal, DepthNormalProvider, FlowProvider, NoFlow, PriorEngine
from nicer_stream.types import FlowPrior, Frame, Intrinsics


def _frame(i: int) -> Frame:
    return Frame(index=i, timestamp=float(i), rgb=np.zeros((4, 5, 3), np.float32), intrinsics=Intrinsics(5, 5, 2, 1.5, 5, 4))


class ConstDepth(DepthNormalProvider):
    name = "const"

    def predict(self, frame: Frame) -> DepthNormal:
        return DepthNormal(depth=np.full((4, 5), float(frame.index), np.float32), normal=None)


class CountingFlow(FlowProvider):
    """Flow whose value encodes (src, dst); counts calls."""

    name = "counting"

    def __init__(self) -> None:
        self.calls = 0

    def flow(self, src: Frame, dst: Frame) -> FlowPrior:
        self.calls += 1
        f = np.zeros((4, 5, 2), np.float32)
        f[..., 0], f[..., 1] = src.index, dst.index
        return FlowPrior(src.index, dst.index, f, np.ones((4, 5), bool))


def test_priors_combine_providers_and_cache_both_directions():
    flow = CountingFlow()
    engine = PriorEngine(ConstDepth(), flow)
    f0, f1, f2 = _frame(0), _frame(1), _frame(2)
    p = engine.priors(f2, [f1, f0])
    assert p.frame_index == 2 and p.provider == "const+counting"
    assert np.all(p.depth == 2.0) and p.normal is None
    assert [(f.src_index, f.dst_index) for f in p.flows] == [(2, 1), (2, 0)]
    assert all(np.all(f.flow[..., 0] == f.src_index) and np.all(f.flow[..., 1] == f.dst_index) for f in p.flows)
    calls = flow.calls
    assert calls == 4  # flow_both: each pair both ways
    back = engine.flow(f1, f2)  # the reverse was cached with the forward one
    assert (back.src_index, back.dst_index) == (1, 2) and flow.calls == calls
    assert engine.flow(f2, f1) is p.flows[0] and flow.calls == calls


def test_flow_cache_is_bounded_and_least_recently_used_goes_first():
    flow = CountingFlow()
    engine = PriorEngine(ConstDepth(), flow, max_cached_flows=2)
    f0, f1, f2 = _frame(0), _frame(1), _frame(2)
    engine.flow(f0, f1)  # caches (1,0) and (0,1)
    engine.flow(f1, f2)  # caches (2,1), (1,2): drops the first pair
    assert flow.calls == 4
    engine.flow(f1, f2)
    assert flow.calls == 4
    engine.flow(f0, f1)
    assert flow.calls == 6


def test_none_flow_gives_no_flows():
    engine = PriorEngine(ConstDepth(), NoFlow())
    assert engine.priors(_frame(1), [_frame(0)]).flows == []
    assert engine.flow(_frame(1), _frame(0)) is None
