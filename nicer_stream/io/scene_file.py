"""scene.pt: the fitted scene (config, bound, model and beta-counter state) for re-rendering."""
from __future__ import annotations

from dataclasses import asdict
from pathlib import Path

import torch

from nicer_stream import config as config_mod
from nicer_stream.config import SlamConfig
from nicer_stream.errors import UserError
from nicer_stream.model.bound import SceneBound
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField

SCENE_FILE = "scene.pt"


def save_scene(out_dir: Path, cfg: SlamConfig, model: SceneModel, beta: BetaField) -> Path:
    path = Path(out_dir) / SCENE_FILE
    torch.save({"config": asdict(cfg), "bound": model.bound.to_dict(),
                "model": model.state_dict(), "beta": beta.state_dict()}, path)
    return path


def load_scene(path: Path, device: str = "cpu") -> tuple[SlamConfig, SceneModel, BetaField]:
    data = torch.load(path, map_location=device, weights_only=True)
    # Settings an older version saved and this one renamed (the frontend's, say) do not shape
    # the scene: skipped; the model's own are checked by its state dict below.
    cfg = config_mod.override(config_mod.SlamConfig(), data["config"], strict=False)
    b = data["bound"]
    model = SceneModel(cfg.model, SceneBound(tuple(b["centre"]), b["half_extent"], b["source"])).to(device)
    # Scenes saved before the initial sphere was stored keep the default one (bound centre).
    missing, unexpected = model.load_state_dict(data["model"], strict=False)
    if unexpected or set(missing) - {"geometry.sphere_centre", "geometry.sphere_radius"}:
        raise UserError(f"{path} does not match this version's scene model: re-run the mapping")
    beta = BetaField(cfg.render).to(device)
    beta.load_state_dict(data["beta"])
    return cfg, model, beta
