"""Omnidata loading through a local hubconf.py (tiny stand-in models) and its conventions."""
from __future__ import annotations

import textwrap

import numpy as np

from nicer_stream.priors import make_depth_normal_provider
from nicer_stream.geometry.depth_normals import view_rays
from nicer_stream.priors.omnidata import omnidata_normals_to_opencv
from nicer_stream.types import Frame, Intrinsics

# Omnidata-encoded normal (OpenGL camera axes, [0, 1]) of a surface tilted upwards:
# (0, 0.5, 0.866) -> in OpenCV axes (y down, z forward): (0, -0.5, -0.866).
N01 = (0.5, 0.75, 0.933)
N_CV = np.array([0.0, -0.5, -0.866])

HUBCONF = textwrap.dedent(
    f"""
    dependencies = ["torch"]
    import torch


    class Tiny(torch.nn.Module):
        def __init__(self, task):
            super().__init__()
            self.task = task
            self.conv = torch.nn.Conv2d(3, 3 if task == "normal" else 1, 3, padding=1)
            self.seen = None

        def forward(self, x):
            self.seen = (tuple(x.shape), float(x.min()), float(x.max()))
            y = torch.sigmoid(self.conv(x))
            if self.task == "depth":
                return y[:, 0]  # Omnidata's depth model returns (B, H, W)
            const = torch.tensor({N01}).view(1, 3, 1, 1)
            return const + 0.0 * y


    def dpt_hybrid_384(pretrained=True, task="normal", **kwargs):
        torch.manual_seed(0)
        return Tiny(task)
    """
)


def test_omnidata_normals_to_opencv_axes():
    np.testing.assert_allclose(omnidata_normals_to_opencv(np.array([0.5, 0.5, 1.0])), [0.0, 0.0, -1.0])
    np.testing.assert_allclose(omnidata_normals_to_opencv(np.array(N01)), N_CV, atol=1e-6)
    np.testing.assert_allclose(omnidata_normals_to_opencv(np.array([1.0, 0.5, 0.5])), [1.0, 0.0, 0.0])


def test_local_hubconf_loads_and_predicts(tmp_path, replica_small):
    (tmp_path / "hubconf.py").write_text(HUBCONF)
    provider = make_depth_normal_provider(f"omnidata:{tmp_path}", "cpu")
    assert provider.name == "omnidata"
    frame: Frame = replica_small[0]
    out = provider.predict(frame)
    h, w = frame.height, frame.width
    assert out.depth.shape == (h, w) and out.depth.dtype == np.float32 and np.isfinite(out.depth).all()
    assert out.normal.shape == (h, w, 3) and out.normal.dtype == np.float32
    # Preprocessing: 384x384; depth input normalised to [-1, 1], normal input left in [0, 1].
    shape_d, lo_d, hi_d = provider.depth_model.seen
    shape_n, lo_n, hi_n = provider.normal_model.seen
    assert shape_d == shape_n == (1, 3, 384, 384)
    assert -1.0 <= lo_d < 0.0 and 0.0 <= lo_n and hi_n <= 1.0 and hi_d <= 1.0
    # Normals: unit, OpenCV axes, facing the camera; at the image centre exactly the converted constant.
    np.testing.assert_allclose(np.linalg.norm(out.normal, axis=-1), 1.0, atol=1e-5)
    assert ((out.normal * view_rays(frame.intrinsics)).sum(-1) <= 0).all()
    np.testing.assert_allclose(out.normal[h // 2, w // 2], N_CV / np.linalg.norm(N_CV), atol=1e-3)


def test_depth_is_resized_back_to_any_frame_size(tmp_path):
    (tmp_path / "hubconf.py").write_text(HUBCONF)
    provider = make_depth_normal_provider(f"omnidata:{tmp_path}")
    rgb = np.random.default_rng(0).random((30, 50, 3)).astype(np.float32)
    out = provider.predict(Frame(0, 0.0, rgb, Intrinsics(40, 40, 24.5, 14.5, 50, 30)))
    assert out.depth.shape == (30, 50) and out.normal.shape == (30, 50, 3)
