"""Configuration: frozen dataclasses, one per component, and the named presets.

`paper` holds the paper's settings (Sec. 3, ../shared/paper); `fast` is sized for a 2-core CPU. A
JSON/TOML file may override any field by its nested name. Each section checks its values when it
is built (type, mode, range), so a wrong value is a one-line error naming its key before a run
starts. Why a default is what it is: docs/decisions.md.
"""
from __future__ import annotations

from nicer_stream.config.checks import FRACTIONS, POSITIVE, SIGNED, Checked, check
from nicer_stream.config.model import ModelConfig, RenderConfig
from nicer_stream.config.mapping import LossConfig, MappingConfig
from nicer_stream.config.tracking import TrackingConfig
from nicer_stream.config.frontend import FrontendConfig
from nicer_stream.config.scene import BoundConfig, MeshConfig
from nicer_stream.config.stereo import StereoConfig
from nicer_stream.config.slam import SlamConfig
from nicer_stream.config.presets import PRESETS, fast, paper, preset
from nicer_stream.config.files import load, override

__all__ = ["FRACTIONS", "POSITIVE", "SIGNED", "Checked", "check", "ModelConfig", "RenderConfig", "LossConfig",
           "MappingConfig", "TrackingConfig", "FrontendConfig", "BoundConfig", "MeshConfig", "StereoConfig",
           "SlamConfig", "PRESETS", "fast", "paper", "preset", "load", "override"]
