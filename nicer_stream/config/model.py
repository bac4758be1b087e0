"""The scene representation and rendering sections."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nicer_stream.config.checks import Checked


@dataclass(frozen=True)
class ModelConfig(Checked):
    """Hierarchical scene representation (Sec. 3.1)."""

    pe_levels: int = 6
    """Positional-encoding frequencies of x for the geometry MLPs."""
    coarse_res: int = 32
    """Coarse dense grid resolution (vertices per axis)."""
    coarse_dim: int = 32
    """Coarse grid feature width."""
    coarse_hidden: int = 64
    """Coarse MLP hidden width (one hidden layer)."""
    fine_levels: int = 8
    """Number of fine dense grids."""
    fine_dim: int = 4
    """Feature width per fine level."""
    fine_res_min: int = 32
    """Coarsest fine resolution (Eq. 2)."""
    fine_res_max: int = 128
    """Finest fine resolution (Eq. 2)."""
    fine_hidden: int = 64
    """Fine MLP hidden width."""
    fine_layers: int = 3
    """Fine MLP hidden layers."""
    geo_feature_dim: int = 32
    """Geometric feature width output by each geometry MLP (z_coarse, z_fine)."""
    color_levels: int = 16
    """Colour hash-grid levels."""
    color_dim: int = 2
    """Colour feature width per level."""
    color_res_min: int = 16
    """Coarsest colour resolution."""
    color_res_max: int = 2048
    """Finest colour resolution."""
    color_log2_table: int = 22
    """log2 of hash-table rows per level (the release uses 24: ~6 GB with Adam state)."""
    color_hidden: int = 64
    """Colour MLP hidden width."""
    color_layers: int = 2
    """Colour MLP hidden layers."""
    view_pe_levels: int = 4
    """Positional-encoding frequencies of the view direction."""
    sphere_radius: float = 0.9
    """Geometric initialisation: SDF = radius - |x| (camera inside a sphere), in normalised units."""
    sphere_centre: Literal["bound", "camera", "auto"] = "auto"
    """SLAM's initial sphere: 'bound' (the bound's centre, `sphere_radius`), 'camera' (the first camera,
    radius its median depth) or 'auto' ('camera' when the camera lies outside the bound's sphere)."""


@dataclass(frozen=True)
class RenderConfig(Checked):
    """Ray sampling and volume rendering (Sec. 3.2)."""

    n_probe: int = 640
    """Uniform samples per ray evaluated without gradient to place the others."""
    n_importance: int = 64
    """Importance samples per ray (with gradient)."""
    n_uniform: int = 32
    """Extra stratified samples per ray (with gradient)."""
    probe_stop_tau: float | None = 16.0
    """A ray's probes stop once its optical depth passes this (the skipped weights sum to less than
    e^-tau); None evaluates every probe. The same samples, computed faster."""
    min_transmittance: float = 0.0
    """With gradient, samples whose estimated transmittance is below this skip the network
    (`render/live_samples.py`); 0: every sample. Mapping keeps 0 (docs/decisions.md)."""
    keep_band_m: float = 0.0
    """With `min_transmittance`: samples within this distance behind a surface go through the network
    anyway (the Eikonal term's points); 0: none. An option (docs/decisions.md)."""
    near_m: float = 0.05
    """Closest sample distance from the camera, metres."""
    beta_mode: Literal["adaptive", "global", "fixed"] = "adaptive"
    """'adaptive' (Eq. 8, voxel counts), 'global' (one learnable beta, VolSDF) or 'fixed'."""
    beta_fixed: float = 0.01
    """Beta for 'fixed' mode and the initial value for 'global' (normalised units)."""
    beta_c0: float = 1.208e-2
    """Eq. 8 constant c0."""
    beta_c1: float = 6.26471e-6
    """Eq. 8 constant c1 (per counted sample)."""
    beta_c2: float = 2.3e-3
    """Eq. 8 constant c2."""
    beta_voxels: int = 64
    """Voxel counter resolution per axis."""
    beta_count_weight: float = 1.0
    """Each mapping sample adds this to its voxel's count; fewer rays than the paper's with a weight
    of paper/ours keep its count-per-effort curve."""
    chunk_rays: int = 2048
    """Rays per chunk when rendering whole images without gradient."""
