"""flush_denormals: denormals are 0 on the calling thread and its OpenMP workers inside the
scope and IEEE outside it; the optimisation loops run inside it; results agree with the reference."""
from dataclasses import replace

import pytest
import torch

from nicer_stream import denormals
from nicer_stream.config import load
from nicer_stream.denormals import flush_denormals
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from sources import open_source
from sources.base import SourceOptions

TINY = torch.finfo(torch.float32).tiny  # smallest normal float32, 1.2e-38


def thread_flags() -> list[bool]:
    """FTZ/DAZ of the calling thread and each of its OpenMP workers, or [] without the helper."""
    mod = denormals._helper()
    return list(mod.get_flush(torch.get_num_threads())) if mod is not None else []


# Without the compiled helper only the calling thread is flushed, and a parallel product is not.
needs_helper = pytest.mark.skipif(not thread_flags(), reason="fpenv helper not built here")


def _denormal_products() -> int:
    """How many of 4M products land as denormals: big enough that every worker thread takes a share."""
    x = torch.full((1 << 22,), 1e-30)
    y = x * 1e-10
    return int(((y != 0) & (y.abs() < TINY)).sum())


@needs_helper
def test_products_are_flushed_inside_the_scope_and_denormal_outside(monkeypatch):
    monkeypatch.setenv("NICER_STREAM_FTZ", "1")
    assert _denormal_products() == 1 << 22
    with flush_denormals():
        assert _denormal_products() == 0
        assert thread_flags() == [True] * torch.get_num_threads()
    assert _denormal_products() == 1 << 22
    assert not any(thread_flags())


@needs_helper
def test_the_scope_nests_and_is_left_on_an_exception(monkeypatch):
    monkeypatch.setenv("NICER_STREAM_FTZ", "1")
    with pytest.raises(RuntimeError):
        with flush_denormals():
            with flush_denormals():
                pass
            assert _denormal_products() == 0  # the inner exit kept the outer scope's setting
            raise RuntimeError("stop")
    assert _denormal_products() == 1 << 22


def test_the_environment_switch_keeps_ieee_denormals(monkeypatch):
    monkeypatch.setenv("NICER_STREAM_FTZ", "0")
    with flush_denormals():
        assert _denormal_products() == 1 << 22


def _tiny_mapper(tiny_toml, tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(tiny_toml)
    cfg = load("fast", path)
    cfg = replace(cfg, model=replace(cfg.model, color_levels=4, color_res_max=64, color_log2_table=12,
                                     fine_levels=2, fine_res_min=16, fine_res_max=24),
                  mapping=replace(cfg.mapping, rays=256, fine_start=0.3, ba_start=1.0))
    frames = list(open_source("synthetic:room?frames=6", SourceOptions(max_side=32, stride=3)))
    mfs = [MapFrame.from_frame(f.without_ground_truth(), None, torch.device("cpu")) for f in frames]
    poses = {f.index: torch.tensor(f.gt_pose, dtype=torch.float32) for f in frames}
    torch.manual_seed(0)
    model = SceneModel(cfg.model, SceneBound(tuple(frames[0].gt_pose[:3, 3]), 3.0, "config"))
    return Mapper(model, BetaField(cfg.render), cfg), model, mfs, poses


@needs_helper
def test_mapping_runs_flushed_and_agrees_with_ieee_denormals(monkeypatch, tiny_toml, tmp_path):
    import nicer_stream.mapping.mapper as mapper_mod

    seen = []
    render = mapper_mod.render_rays
    monkeypatch.setattr(mapper_mod, "render_rays", lambda *a, **k: (seen.append(_denormal_products() == 0), render(*a, **k))[1])
    results = {}
    for ftz in ("0", "1"):
        monkeypatch.setenv("NICER_STREAM_FTZ", ftz)
        seen.clear()
        mapper, model, mfs, poses = _tiny_mapper(tiny_toml, tmp_path)
        stats = mapper.optimise(mfs, poses, 6, color_start=0.0)
        results[ftz] = (stats.loss, [p.detach().clone() for p in model.parameters()])
        assert seen == [ftz == "1"] * 6  # every iteration inside the scope, none outside it
        assert _denormal_products() == 1 << 22  # and nothing left behind
    (loss0, params0), (loss1, params1) = results["0"], results["1"]
    assert loss1 == pytest.approx(loss0, rel=1e-4)
    for a, b in zip(params0, params1):
        assert torch.allclose(a, b, rtol=1e-4, atol=1e-6)
