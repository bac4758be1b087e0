"""SlamSystem.finish(): the closing mapping call of the schedule and its own colour start and
learning rates; every mapping call's progress callback."""
from dataclasses import replace

from nicer_stream.config import load
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.slam.events import MapUpdated
from nicer_stream.slam.system import SlamSystem
from sources import open_source
from sources.base import SourceOptions


def _run(cfg, progress=None):
    slam = SlamSystem(cfg, progress=progress)
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


def test_every_mapping_call_reports_progress_under_its_label(tiny_config):
    cfg = load("fast", tiny_config)  # no priors: first-frame start; mapped at frames 2 and 4, then the closing call
    calls: dict[str, list[tuple[int, int]]] = {}

    def progress(label):
        calls[label] = []
        return lambda it, iters, loss: calls[label].append((it, iters))

    events, closing = _run(cfg, progress)
    maps = [e for e in events + closing if isinstance(e, MapUpdated)]
    assert list(calls) == ["first mapping (frame 0)", "mapping @ frame 2", "mapping @ frame 4",
                           "closing mapping @ frame 4"]
    for (label, got), e in zip(calls.items(), maps):  # one call per iteration, from the first one on
        assert got == [(i, e.iters) for i in range(e.iters)], label


def test_old_keyframes_are_kept_at_half_resolution(tiny_config):
    cfg = load("fast", tiny_config)  # keyframes every 2 frames
    slam = SlamSystem(replace(cfg, mapping=replace(cfg.mapping, full_res_keyframes=1)))
    for f in open_source("synthetic:room?frames=9", SourceOptions(max_side=32)):
        slam.step(f.without_ground_truth())
    slam.finish()  # mapping windows drew halved keyframes too
    kf = [k for k in slam.keyframes if k in slam.frames]
    full = slam.frames[slam.order[0]].rgb.shape
    newest = slam.frames[kf[-1]].rgb.shape
    assert newest == full
    old = [k for k in kf[:-1] if k != slam.order[0]]
    assert old and all(slam.frames[k].rgb.shape[0] == full[0] // 2 for k in old)
    assert all(not slam.frames[k].flows for k in old)
    assert all(k not in f.flows for f in slam.frames.values() for k in old)


def test_only_the_closing_call_takes_the_final_colour_start_and_learning_rate(tiny_config, monkeypatch):
    cfg = load("fast", tiny_config)
    cfg = replace(cfg, mapping=replace(cfg.mapping, final_iters=3, final_color_start=0.0, final_lr_end_factor=0.2))
    calls = []
    optimise = Mapper.optimise

    def spy(self, frames, poses, iters, **kw):
        calls.append((kw.get("color_start"), kw.get("lr_end", 1.0), bool(kw.get("ba_indices"))))
        return optimise(self, frames, poses, iters, **kw)

    monkeypatch.setattr(Mapper, "optimise", spy)
    _run(cfg)
    assert len(calls) == 4  # the first mapping, frames 2 and 4, the closing call
    assert calls[-1] == (0.0, 0.2, False)
    assert all(lr_end == 1.0 for _, lr_end, _ in calls[:-1])
    assert all(color_start is None for color_start, _, _ in calls[1:-1])  # at ba_start, the paper's
