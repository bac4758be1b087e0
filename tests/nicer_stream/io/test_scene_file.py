"""scene.pt: a saved scene loads with the same field, including its initial sphere."""
import pytest
import torch

from nicer_stream.config import SlamConfig
from nicer_stream.errors import UserError
from nicer_stream.io.scene_file import load_scene, save_scene
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField


def _scene():
    torch.manual_seed(0)
    cfg = SlamConfig()
    model = SceneModel(cfg.model, SceneBound((0.5, -0.2, 2.0), 2.5, "test"))
    model.geometry.set_sphere(torch.tensor([-0.2, 0.1, -0.8]), 0.8)
    return cfg, model, BetaField(cfg.render)


def test_round_trip_keeps_the_sphere(tmp_path):
    cfg, model, beta = _scene()
    save_scene(tmp_path, cfg, model, beta)
    _, loaded, _ = load_scene(tmp_path / "scene.pt")
    x = torch.rand(64, 3) * 2 - 1
    with torch.no_grad():
        assert torch.equal(loaded.geometry(x).sdf, model.geometry(x).sdf)
    assert float(loaded.geometry.sphere_radius) == pytest.approx(0.8)


def test_scene_saved_before_the_sphere_buffers_loads(tmp_path):
    cfg, model, beta = _scene()
    save_scene(tmp_path, cfg, model, beta)
    data = torch.load(tmp_path / "scene.pt", weights_only=True)
    for k in ("geometry.sphere_centre", "geometry.sphere_radius"):
        del data["model"][k]
    torch.save(data, tmp_path / "scene.pt")
    _, loaded, _ = load_scene(tmp_path / "scene.pt")
    assert torch.equal(loaded.geometry.sphere_centre, torch.zeros(3))  # the old default sphere


def test_foreign_state_is_a_clear_error(tmp_path):
    cfg, model, beta = _scene()
    save_scene(tmp_path, cfg, model, beta)
    data = torch.load(tmp_path / "scene.pt", weights_only=True)
    data["model"]["stray.weight"] = torch.zeros(1)
    torch.save(data, tmp_path / "scene.pt")
    with pytest.raises(UserError, match="re-run"):
        load_scene(tmp_path / "scene.pt")


def test_settings_another_version_saved_are_skipped_but_known_ones_kept(tmp_path):
    """A scene saved before a frontend setting was renamed (`ba_keyframes`) still loads, with the
    saved values of the settings this version knows."""
    cfg, model, beta = _scene()
    save_scene(tmp_path, cfg, model, beta)
    data = torch.load(tmp_path / "scene.pt", weights_only=True)
    data["config"]["frontend"]["ba_keyframes"] = 6
    data["config"]["render"]["n_probe"] = 17
    torch.save(data, tmp_path / "scene.pt")
    loaded_cfg, _, _ = load_scene(tmp_path / "scene.pt")
    assert loaded_cfg.render.n_probe == 17
    assert not hasattr(loaded_cfg.frontend, "ba_keyframes")
