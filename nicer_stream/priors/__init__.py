"""Monocular prior providers (depth + normal, optical flow) addressed by name.

Depth/normal: `auto` (a learned provider whose weights are on this machine, else `stereo`),
`none`, `oracle` (from GT with a monocular network's errors, evaluation
only), `oracle:clean` (nearly GT, debugging only), `stereo` (plane sweep between keyframes
with the SLAM's poses: no GT, no weights; `run` only), `cache:DIR`,
`omnidata[:PATH_OR_HUB]`, `depth-anything[:MODEL_ID_OR_PATH]`.
Flow: `dis` (default), `none`, `oracle`, `raft`, `cache:DIR`.
Network providers import their heavy dependencies only when chosen.
"""
from __future__ import annotations

import torch

from nicer_stream.errors import UserError
from nicer_stream.priors.base import (
    DepthNormal,
    DepthNormalProvider,
    FlowProvider,
    NoDepthNormal,
    NoFlow,
    PriorEngine,
)

DEPTH_NORMAL_PROVIDERS = ("auto", "none", "stereo", "oracle", "oracle:clean", "cache:DIR", "omnidata[:PATH_OR_HUB]", "depth-anything[:MODEL_ID_OR_PATH]")
FLOW_PROVIDERS = ("dis", "none", "oracle", "raft", "cache:DIR")
DEFAULT_FLOW = "dis"

__all__ = [
    "DepthNormal", "DepthNormalProvider", "FlowProvider", "NoDepthNormal", "NoFlow", "PriorEngine",
    "make_depth_normal_provider", "make_flow_provider", "DEPTH_NORMAL_PROVIDERS", "FLOW_PROVIDERS",
]


def _split(name: str) -> tuple[str, str]:
    """'kind:arg' -> ('kind', 'arg'); 'kind' -> ('kind', '')."""
    kind, _, arg = name.strip().partition(":")
    return kind, arg


def _cache_dir(arg: str, name: str) -> str:
    if not arg:
        raise UserError(f"prior provider '{name}' needs a directory: cache:DIR")
    return arg


def make_depth_normal_provider(name: str, device: str | torch.device = "cpu",
                                auto_fallback: str = "stereo", seed: int = 0) -> DepthNormalProvider:
    """Depth/normal provider named `name` (see DEPTH_NORMAL_PROVIDERS); models go to `device`;
    `auto` without learned weights is `auto_fallback`; `seed` (the config's) draws the oracle's errors."""
    kind, arg = _split(name)
    if kind == "auto" and not arg:
        from nicer_stream.priors.auto import choose

        chosen, reason = choose(fallback=auto_fallback)
        provider = make_depth_normal_provider(chosen, device, seed=seed)
        provider.auto_reason = reason
        return provider
    if kind == "none" and not arg:
        return NoDepthNormal()
    if kind == "stereo" and not arg:
        from nicer_stream.priors.stereo import StereoDepthNormal

        return StereoDepthNormal()
    if kind == "oracle" and arg in ("", "clean"):
        from nicer_stream.priors.oracle import OracleCorruption, OracleDepthNormal

        return OracleDepthNormal(seed, OracleCorruption.clean() if arg else OracleCorruption())
    if kind == "cache":
        from nicer_stream.priors.cache import CacheDepthNormal

        return CacheDepthNormal(_cache_dir(arg, name))
    if kind == "omnidata":
        from nicer_stream.priors.omnidata import DEFAULT_REPO, OmnidataProvider

        return OmnidataProvider(arg or DEFAULT_REPO, device=device)
    if kind == "depth-anything":
        from nicer_stream.priors.depth_anything import DEFAULT_MODEL, DepthAnythingProvider

        return DepthAnythingProvider(arg or DEFAULT_MODEL, device=device)
    raise UserError(f"unknown depth/normal prior provider '{name}': use one of {', '.join(DEPTH_NORMAL_PROVIDERS)}")


def make_flow_provider(name: str = DEFAULT_FLOW, device: str | torch.device = "cpu") -> FlowProvider:
    """Flow provider named `name` (see FLOW_PROVIDERS); RAFT runs on `device`."""
    kind, arg = _split(name)
    if kind == "cache":
        from nicer_stream.priors.cache import CacheFlow

        return CacheFlow(_cache_dir(arg, name))
    if arg:
        raise UserError(f"unknown flow provider '{name}': use one of {', '.join(FLOW_PROVIDERS)}")
    if kind == "none":
        return NoFlow()
    if kind == "dis":
        from nicer_stream.priors.dis_flow import DisFlowProvider

        return DisFlowProvider()
    if kind == "oracle":
        from nicer_stream.priors.oracle import OracleFlow

        return OracleFlow()
    if kind == "raft":
        from nicer_stream.priors.raft_flow import RaftFlowProvider

        return RaftFlowProvider(device=device)
    raise UserError(f"unknown flow provider '{name}': use one of {', '.join(FLOW_PROVIDERS)}")
