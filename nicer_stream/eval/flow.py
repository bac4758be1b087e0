"""Optical-flow metrics: end-point error against a ground-truth flow, and what a validity mask keeps.

Flows are (H, W, 2) float (du, dv) in pixels from the source frame to the destination
frame (docs/conventions.md); masks are (H, W) bool. Every function is pixel-wise, so
several pairs can be pooled by concatenating them along the first axis.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BAD_EPE_PX = 3.0
"""End-point error (pixels) above which a flow vector counts as bad (the issue's 3 px)."""


def epe_map(flow: np.ndarray, gt_flow: np.ndarray) -> np.ndarray:
    """(H, W, 2) flow and GT flow (pixels) -> (H, W) float64 end-point error |flow - gt| in pixels."""
    if flow.shape != gt_flow.shape or flow.shape[-1] != 2:
        raise ValueError(f"flow shapes differ or are not (..., 2): {flow.shape} vs {gt_flow.shape}")
    return np.linalg.norm(flow.astype(np.float64) - gt_flow.astype(np.float64), axis=-1)


def end_point_error(flow: np.ndarray, gt_flow: np.ndarray, mask: np.ndarray | None = None) -> float:
    """Mean end-point error in pixels over the (H, W) bool `mask` (all pixels if None); NaN if it is empty."""
    epe = epe_map(flow, gt_flow)
    sel = epe if mask is None else epe[mask]
    return float(sel.mean()) if sel.size else float("nan")


def _ratio(num: int, den: int) -> float:
    # NaN rather than 0 when there is nothing to count: "no bad pixel" is not "mask removed them all".
    return num / den if den else float("nan")


@dataclass(frozen=True)
class FlowErrorReport:
    """Flow accuracy of one pair (or of pooled pairs) against GT flow; EPEs in pixels, fractions in [0, 1]."""

    gt_median_px: float
    """Median GT flow magnitude over GT-valid pixels (how large the motion is)."""
    mean_epe: float
    """Mean EPE over GT-valid pixels."""
    masked_epe: float
    """Mean EPE over GT-valid pixels that the estimate's validity (consistency) mask keeps."""
    bad_fraction: float
    """Fraction of GT-valid pixels with EPE > `BAD_EPE_PX`."""
    bad_kept: float
    """Fraction of those bad pixels that the mask keeps (NaN when there are none)."""
    valid_fraction: float
    """Fraction of all pixels that the mask keeps."""
    n_bad: int
    """Number of bad pixels (the sample size behind `bad_kept`)."""


def flow_error_report(
    flow: np.ndarray, kept: np.ndarray, gt_flow: np.ndarray, gt_valid: np.ndarray, bad_px: float = BAD_EPE_PX
) -> FlowErrorReport:
    """Compare an estimated flow (H, W, 2) with its mask `kept` (H, W) bool to GT flow (H, W, 2) valid on `gt_valid`."""
    epe = epe_map(flow, gt_flow)
    gt_valid, kept = gt_valid.astype(bool), kept.astype(bool)
    bad = gt_valid & (epe > bad_px)
    n_valid, n_bad = int(gt_valid.sum()), int(bad.sum())
    mag = np.linalg.norm(gt_flow[gt_valid], axis=-1)
    return FlowErrorReport(
        gt_median_px=float(np.median(mag)) if mag.size else float("nan"),
        mean_epe=end_point_error(flow, gt_flow, gt_valid),
        masked_epe=end_point_error(flow, gt_flow, gt_valid & kept),
        bad_fraction=_ratio(n_bad, n_valid),
        bad_kept=_ratio(int((bad & kept).sum()), n_bad),
        valid_fraction=float(kept.mean()) if kept.size else float("nan"),
        n_bad=n_bad,
    )
