"""The whole configuration of a run: one field per section."""
from __future__ import annotations

from dataclasses import dataclass, field

from nicer_stream.config.checks import Checked
from nicer_stream.config.frontend import FrontendConfig
from nicer_stream.config.mapping import LossConfig, MappingConfig
from nicer_stream.config.model import ModelConfig, RenderConfig
from nicer_stream.config.scene import BoundConfig, MeshConfig
from nicer_stream.config.stereo import StereoConfig
from nicer_stream.config.tracking import TrackingConfig


@dataclass(frozen=True)
class SlamConfig(Checked):
    """Everything a run needs; each component receives only its own part."""

    preset: str = "paper"
    """Name of the preset this config started from."""
    max_side: int | None = None
    """Resize input so the longer side is at most this (None: native)."""
    model: ModelConfig = field(default_factory=ModelConfig)
    """Scene representation."""
    render: RenderConfig = field(default_factory=RenderConfig)
    """Rendering."""
    loss: LossConfig = field(default_factory=LossConfig)
    """Loss weights."""
    mapping: MappingConfig = field(default_factory=MappingConfig)
    """Mapping."""
    tracking: TrackingConfig = field(default_factory=TrackingConfig)
    """Tracking."""
    bound: BoundConfig = field(default_factory=BoundConfig)
    """Scene bound."""
    frontend: FrontendConfig = field(default_factory=FrontendConfig)
    """Classical frontend settings (used when `tracking.frontend = 'classical'`)."""
    stereo: StereoConfig = field(default_factory=StereoConfig)
    """Plane-sweep stereo priors (used with `--priors stereo`, and with monocular priors when
    `stereo.mono_fusion`)."""
    mesh: MeshConfig = field(default_factory=MeshConfig)
    """Mesh extraction."""
    seed: int = 0
    """Random seed."""
