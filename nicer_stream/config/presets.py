"""The named presets: `paper` (the paper's settings) and `fast` (sized for a 2-core CPU)."""
from __future__ import annotations

from nicer_stream.config.mapping import LossConfig, MappingConfig
from nicer_stream.config.model import ModelConfig, RenderConfig
from nicer_stream.config.slam import SlamConfig
from nicer_stream.config.scene import MeshConfig
from nicer_stream.config.stereo import StereoConfig
from nicer_stream.config.tracking import TrackingConfig
from nicer_stream.errors import UserError
from nicer_stream.losses.weights import LossWeights


def paper() -> SlamConfig:
    """The paper's settings (Sec. 3.4 and the release's hyperparameters)."""
    return SlamConfig(preset="paper")


def fast() -> SlamConfig:
    """Sized for a 2-core CPU: 320 px images, fewer rays, samples and iterations. Where it departs
    from the paper for other reasons than cost, docs/decisions.md ("The `fast` preset") says why."""
    return SlamConfig(
        preset="fast",
        max_side=320,
        model=ModelConfig(color_levels=12, color_res_max=512, color_log2_table=17),
        render=RenderConfig(n_probe=32, n_importance=12, n_uniform=4, beta_count_weight=500.0),
        loss=LossConfig(weights=LossWeights(depth=10.0, flow=0.01, normal_l1=0.2, normal_angular=0.2)),
        mapping=MappingConfig(iters=60, first_iters=200, rays=1024, eikonal_points=256, batch_iters=350,
                              init="two_view", keyframes="view", keyframe_every=5, final_iters=100,
                              final_color_start=0.25, final_lr_end_factor=0.1),
        tracking=TrackingConfig(iters=20, rays=512, lr=3e-3, init="flow", keep="last", min_count=1000.0,
                                n_probe=32, n_importance=12, n_uniform=0, frontend="classical",
                                refine="keyframes", rejected_keyframe="frontend"),
        stereo=StereoConfig(mono_fusion=True),
        mesh=MeshConfig(resolution=192),
    )


PRESETS = {"paper": paper, "fast": fast}


def preset(name: str) -> SlamConfig:
    """A named preset; unknown names are a UserError."""
    if name not in PRESETS:
        raise UserError(f"unknown preset '{name}': use one of {', '.join(PRESETS)}")
    return PRESETS[name]()
