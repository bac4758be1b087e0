"""Mapping losses of NICER-SLAM (paper Sec. 3.3). Per-ray inputs are (N, ...) tensors."""
from nicer_stream.losses.eikonal import eikonal_loss
from nicer_stream.losses.flow import flow_loss
from nicer_stream.losses.mono_depth import mono_depth_loss, scale_shift_lstsq
from nicer_stream.losses.normal import normal_loss
from nicer_stream.losses.photometric import masked_mean, rgb_l1
from nicer_stream.losses.warping import bilinear_sample, warp_pixels, warping_loss
from nicer_stream.losses.weights import LossTerms, LossWeights, total_loss

__all__ = [
    "LossTerms",
    "LossWeights",
    "bilinear_sample",
    "eikonal_loss",
    "flow_loss",
    "masked_mean",
    "mono_depth_loss",
    "normal_loss",
    "rgb_l1",
    "scale_shift_lstsq",
    "total_loss",
    "warp_pixels",
    "warping_loss",
]
