"""Depth Anything through transformers, with a tiny randomly initialised checkpoint made here."""
from __future__ import annotations

import numpy as np
import pytest

from nicer_stream.priors.depth_anything import disparity_to_depth
from nicer_stream.geometry.depth_normals import view_rays
from nicer_stream.types import Frame, Intrinsics


def test_disparity_to_depth_is_decreasing_and_bounded():
    disp = np.linspace(-0.1, 4.0, 50, dtype=np.float32)[None, :]
    d = disparity_to_depth(disp, eps=0.05)
    assert d.dtype == np.float32 and np.isfinite(d).all()
    assert (np.diff(d[0]) <= 0).all() and (np.diff(d[0, 5:]) < 0).all()  # nearer where disparity is larger
    assert d.max() == pytest.approx(1 / 0.05)  # negative disparity clipped to 0
    # Invariant to the disparity's scale (only its shape matters).
    np.testing.assert_allclose(disparity_to_depth(7.0 * disp), d, rtol=1e-5)


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory):
    """A ~0.3 MB Depth Anything (DINOv2 backbone) saved with save_pretrained, plus its processor."""
    transformers = pytest.importorskip("transformers")
    import torch

    torch.manual_seed(0)
    backbone = transformers.Dinov2Config(
        hidden_size=32, num_hidden_layers=2, num_attention_heads=2, intermediate_size=64,
        image_size=56, patch_size=14, out_features=["stage1", "stage2"], reshape_hidden_states=False,
    )
    config = transformers.DepthAnythingConfig(
        backbone_config=backbone, reassemble_hidden_size=32, neck_hidden_sizes=[16, 32],
        fusion_hidden_size=16, head_hidden_size=8, reassemble_factors=[1, 0.5],
    )
    path = tmp_path_factory.mktemp("depth_anything_tiny")
    transformers.DepthAnythingForDepthEstimation(config).save_pretrained(path)
    transformers.DPTImageProcessor(
        do_resize=True, size={"height": 56, "width": 56}, keep_aspect_ratio=True, ensure_multiple_of=14,
        image_mean=[0.485, 0.456, 0.406], image_std=[0.229, 0.224, 0.225],
    ).save_pretrained(path)
    return path


def test_tiny_checkpoint_loads_by_path_and_predicts(tiny_checkpoint):
    from nicer_stream.priors import make_depth_normal_provider

    provider = make_depth_normal_provider(f"depth-anything:{tiny_checkpoint}", "cpu")
    assert provider.name == "depth-anything"
    rgb = np.random.default_rng(0).random((45, 70, 3)).astype(np.float32)
    intr = Intrinsics(60, 60, 34.5, 22, 70, 45)
    out = provider.predict(Frame(0, 0.0, rgb, intr))
    assert out.depth.shape == (45, 70) and out.depth.dtype == np.float32
    assert np.isfinite(out.depth).all() and (out.depth > 0).all()
    assert out.normal.shape == (45, 70, 3) and np.isfinite(out.normal).all()
    np.testing.assert_allclose(np.linalg.norm(out.normal, axis=-1), 1.0, atol=1e-5)
    assert ((out.normal * view_rays(intr)).sum(-1) <= 0).all()


def test_missing_model_is_a_one_line_user_error(tmp_path):
    pytest.importorskip("transformers")
    from nicer_stream.errors import UserError
    from nicer_stream.priors import make_depth_normal_provider

    with pytest.raises(UserError) as e:
        make_depth_normal_provider(f"depth-anything:{tmp_path / 'missing'}")
    assert "\n" not in str(e.value) and "depth-anything:" in str(e.value)
