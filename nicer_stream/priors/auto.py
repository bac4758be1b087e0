"""`--priors auto` (the default): a learned provider when its weights are already on this machine,
else `stereo`. Only local caches are looked at: choosing never touches the network."""
from __future__ import annotations

import os
from pathlib import Path

import torch


def _hf_cache() -> Path:
    if os.environ.get("HF_HUB_CACHE"):
        return Path(os.environ["HF_HUB_CACHE"])
    home = Path(os.environ.get("HF_HOME", Path.home() / ".cache" / "huggingface"))
    return home / "hub"


def learned_weights() -> tuple[str | None, str]:
    """(provider name or None, where it looked / what it found): Omnidata in torch hub's cache
    (its hub repo and checkpoints), Depth Anything V2 Small in the Hugging Face cache."""
    hub = Path(torch.hub.get_dir())
    omni = hub / "alexsax_omnidata_tools_main"
    ckpts = hub / "checkpoints"
    if omni.is_dir() and ckpts.is_dir() and any("omnidata" in p.name for p in ckpts.iterdir()):
        return "omnidata", f"Omnidata weights in {hub}"
    da = _hf_cache() / "models--depth-anything--Depth-Anything-V2-Small-hf" / "snapshots"
    if da.is_dir() and any(da.iterdir()):
        return "depth-anything", f"Depth Anything V2 weights in {da.parent}"
    return None, f"no learned weights in {hub} or {_hf_cache()}"


def choose(learned: tuple[str | None, str] | None = None, fallback: str = "stereo") -> tuple[str, str]:
    """(provider name, one-line reason) for `auto`: the learned provider, else `fallback` (`map`
    takes per-frame priors, so its fallback is `none` rather than the SLAM's stereo)."""
    name, where = learned if learned is not None else learned_weights()
    if name is not None:
        return name, f"auto chose {name}: {where}"
    return fallback, f"auto chose {fallback}: {where}"
