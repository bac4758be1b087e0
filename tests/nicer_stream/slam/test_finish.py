"""SlamSystem.finish(): the closing mapping call of the schedule."""
from dataclasses import replace

from nicer_stream.config import load
from nicer_stream.slam.events import MapUpdated
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def _run(cfg):
    slam = SlamSystem(cfg)
    events = []
    for f in open_source("synthetic:room?frames=5", SourceOptions(max_side=32)):
        events += slam.step(f.without_ground_truth())
    return events, slam.finish()


def test_final_iters_adds_a_closing_call_even_after_a_scheduled_one(tiny_config):
    cfg = load("fast", tiny_config)  # mapping every 2 frames: frames 2 and 4 are mapped by the schedule
    events, closing = _run(replace(cfg, mapping=replace(cfg.mapping, final_iters=None)))
    assert [e.index for e in events if isinstance(e, MapUpdated)][-1] == 4
    assert closing == []  # the paper's schedule: the last frame was just mapped
    _, closing = _run(replace(cfg, mapping=replace(cfg.mapping, final_iters=6)))
    assert len(closing) == 1 and isinstance(closing[0], MapUpdated)
    assert closing[0].index == 4 and closing[0].iters == 6 and 4 in closing[0].window
