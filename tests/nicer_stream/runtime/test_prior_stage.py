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
