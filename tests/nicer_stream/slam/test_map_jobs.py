"""Mapping jobs: the copies a job works on are its own; snapshots are frozen copies of the map."""
import torch

from nicer_stream.config import load
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.slam.map_jobs import InlineMapping, job_frames, take_snapshot
from nicer_stream.types import Intrinsics


def test_job_frames_share_images_but_not_the_flow_dicts():
    f = MapFrame(3, 0.1, Intrinsics(10, 10, 4, 4, 8, 8), torch.rand(8, 8, 3))
    f.flows[1] = (torch.zeros(8, 8, 2), torch.ones(8, 8, dtype=torch.bool))
    (copy,) = job_frames([f])
    f.flows[2] = f.flows[1]  # tracking adds a flow while the job runs
    assert list(copy.flows) == [1] and copy.rgb is f.rgb and copy.index == 3


def test_snapshot_is_a_frozen_copy_that_mapping_steps_do_not_change(tiny_config):
    cfg = load("fast", tiny_config)
    model, beta = SceneModel(cfg.model, SceneBound((0, 0, 0), 1.0, "config")), BetaField(cfg.render)
    x = torch.rand(64, 3) * 2 - 1
    snap = take_snapshot(model, beta, 7)
    before = snap.model.geometry(x).sdf.detach().clone()
    assert snap.version == 7 and not any(p.requires_grad for p in snap.model.parameters())
    # Equal up to rounding: the frozen copy's products may take another kernel (no gradient).
    assert torch.allclose(before, model.geometry(x).sdf.detach(), atol=1e-6)
    with torch.no_grad():  # a mapping step on the live map
        for p in model.parameters():
            p.add_(0.1)
        beta.counts += 5
    model.parameters_changed()
    assert not torch.allclose(model.geometry(x).sdf.detach(), before, atol=1e-3)
    assert torch.equal(snap.model.geometry(x).sdf.detach(), before)
    assert float(snap.beta.counts.sum()) == 0.0


def test_inline_mapping_runs_at_submit_and_hands_each_result_back_once():
    ex, ran = InlineMapping(), []
    ex.submit("job", lambda j: ran.append(j) or f"result of {j}")
    assert ran == ["job"] and not ex.busy()
    assert ex.poll() == ["result of job"] and ex.drain() == []
