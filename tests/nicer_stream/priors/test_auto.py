"""`--priors auto`: a learned provider only when its weights are cached here, else stereo."""
import torch

from nicer_stream.priors import make_depth_normal_provider
from nicer_stream.priors.auto import choose, learned_weights


def test_auto_takes_stereo_without_cached_weights(tmp_path, monkeypatch):
    monkeypatch.setattr(torch.hub, "get_dir", lambda: str(tmp_path / "hub"))
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hf"))
    assert learned_weights()[0] is None
    p = make_depth_normal_provider("auto")
    assert p.name == "stereo" and p.auto_reason.startswith("auto chose stereo: no learned weights")


def test_auto_finds_cached_depth_anything(tmp_path, monkeypatch):
    monkeypatch.setattr(torch.hub, "get_dir", lambda: str(tmp_path / "hub"))
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path / "hf"))
    (tmp_path / "hf" / "models--depth-anything--Depth-Anything-V2-Small-hf" / "snapshots" / "abc").mkdir(parents=True)
    name, where = learned_weights()
    assert name == "depth-anything" and str(tmp_path / "hf") in where
    (tmp_path / "hub" / "alexsax_omnidata_tools_main").mkdir(parents=True)
    (tmp_path / "hub" / "checkpoints").mkdir()
    (tmp_path / "hub" / "checkpoints" / "omnidata_dpt_depth_v2.ckpt").write_bytes(b"")
    assert learned_weights()[0] == "omnidata"  # Omnidata first: it has normals too
    assert choose(("omnidata", "x"))[0] == "omnidata"
