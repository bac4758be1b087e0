"""Building MapFrames (observations + priors) from source frames."""
from __future__ import annotations

import torch

from nicer_stream.config import SlamConfig
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.priors import PriorEngine, make_depth_normal_provider, make_flow_provider
from nicer_stream.types import Frame


def make_engine(priors: str, flow: str | None, device, auto_fallback: str = "stereo", seed: int = 0) -> PriorEngine:
    """Depth/normal provider `priors` (`auto` without learned weights: `auto_fallback`); flow
    defaults to `oracle` with `oracle:clean` priors, else `dis` (the realistic `oracle` imitates a
    user's priors: its flow is the default provider's); `seed`: the config's, for the oracle."""
    flow = flow or ("oracle" if priors == "oracle:clean" else "dis")
    return PriorEngine(make_depth_normal_provider(priors, device, auto_fallback, seed), make_flow_provider(flow, device))


def provider_names(engine: PriorEngine) -> list[str]:
    return [engine.depth_normal.name, engine.flow_provider.name]


def map_frame(frame: Frame, engine: PriorEngine, flow_to: list[Frame], device) -> MapFrame:
    """Priors for `frame` (the oracle provider may read its GT) -> a MapFrame with GT removed."""
    pri = engine.priors(frame, flow_to)
    return MapFrame.from_frame(frame.without_ground_truth(), pri, torch.device(device))


def fuses_stereo(cfg: SlamConfig, provider: str) -> bool:
    """Whether the keyframes' monocular depth is fitted to their own plane-sweep stereo
    (`stereo.mono_fusion`): for every provider that gives depth, i.e. not `none` nor `stereo`."""
    return cfg.stereo.mono_fusion and provider not in ("none", "stereo")
