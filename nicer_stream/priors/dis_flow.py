"""OpenCV DIS optical flow (preset MEDIUM) with a forward/backward consistency mask.

Measured on this CPU (docs: /work/shared/reference/priors-offline.md): about
0.6 px end-point error for 3 px motion, 2 px for 12 px, 15-30 ms per pair at 640x480.
The consistency mask's alpha/beta: see flow_consistency.consistency_mask.
"""
from __future__ import annotations

import cv2
import numpy as np

from nicer_stream.grey import to_grey_u8
from nicer_stream.priors.base import FlowProvider
from nicer_stream.priors.flow_consistency import consistency_mask
from nicer_stream.types import FlowPrior, Frame


def dis_flow(gray_src: np.ndarray, gray_dst: np.ndarray, preset: int = cv2.DISOPTICAL_FLOW_PRESET_MEDIUM) -> np.ndarray:
    """(H, W) uint8 pair -> (H, W, 2) float32 flow (du, dv) in pixels, src -> dst."""
    dis = cv2.DISOpticalFlow_create(preset)
    return dis.calc(gray_src, gray_dst, None).astype(np.float32)


class DisFlowProvider(FlowProvider):
    """The default `dis` flow provider: DIS both ways, valid = consistent and in-image."""

    name = "dis"

    def __init__(self, alpha: float = 0.005, beta: float = 0.1) -> None:
        self.alpha = alpha
        self.beta = beta

    def flow_both(self, a: Frame, b: Frame) -> tuple[FlowPrior, FlowPrior]:
        if a.rgb.shape != b.rgb.shape:
            # DIS needs same-sized images; sources resize every frame alike.
            raise ValueError(f"frames {a.index} and {b.index} differ in size: {a.rgb.shape} vs {b.rgb.shape}")
        ga, gb = to_grey_u8(a.rgb), to_grey_u8(b.rgb)  # uint8: what DIS takes
        fw, bw = dis_flow(ga, gb), dis_flow(gb, ga)
        return (
            FlowPrior(a.index, b.index, fw, consistency_mask(fw, bw, self.alpha, self.beta)),
            FlowPrior(b.index, a.index, bw, consistency_mask(bw, fw, self.alpha, self.beta)),
        )
