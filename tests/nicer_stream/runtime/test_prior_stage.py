"""The prior stage: flows between each new frame and the kept keyframes (both ways) and from
the previous frame to it (the tracker's flow initialisation)."""
from nicer_stream.priors import PriorEngine
from nicer_stream.priors.oracle import OracleDepthNormal, OracleFlow
from nicer_stream.runtime.prior_stage import PriorStage
from sources import open_source
from sources.base import SourceOptions


def _pairs(pri):
    return {(f.src_index, f.dst_index) for f in pri.flows}


def test_flows_to_keyframes_and_from_the_previous_frame():
    frames = list(open_source("synthetic:room?frames=5", SourceOptions(max_side=32)))
    stage = PriorStage(PriorEngine(OracleDepthNormal(), OracleFlow()), keyframes_kept=2)
    assert _pairs(stage(frames[0])) == set()
    stage.add_keyframe(frames[0])
    assert _pairs(stage(frames[1])) == {(1, 0), (0, 1)}  # the previous frame is the keyframe: once
    assert _pairs(stage(frames[2])) == {(2, 0), (0, 2), (1, 2)}
    stage.add_keyframe(frames[2])
    assert _pairs(stage(frames[3])) == {(3, 0), (0, 3), (3, 2), (2, 3)}


def test_deferred_flows_are_the_flows_the_frame_would_have_had():
    frames = list(open_source("synthetic:room?frames=5", SourceOptions(max_side=32)))
    eager = PriorStage(PriorEngine(OracleDepthNormal(), OracleFlow()), keyframes_kept=2)
    lazy = PriorStage(PriorEngine(OracleDepthNormal(), OracleFlow()), keyframes_kept=2)
    for f in frames:
        want = eager(f)
        got = lazy(f, flows=False)
        assert got.flows == [] and got.depth is not None
        if f.index in (0, 2):  # a keyframe announced after its step, as the runtime does
            eager.add_keyframe(f)
            later = lazy.deferred_flows()  # asked for while stepping (before the announcement)
            lazy.add_keyframe(f)
        else:
            later = lazy.deferred_flows()
        assert [(p.src_index, p.dst_index) for p in later.flows] == [(p.src_index, p.dst_index) for p in want.flows]
        for a, b in zip(later.flows, want.flows):
            assert (a.flow == b.flow).all() and (a.valid == b.valid).all()
