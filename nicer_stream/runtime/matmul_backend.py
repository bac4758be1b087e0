"""Send torch's float32 matmuls to oneDNN where oneDNN computes them in float32 on this CPU.

torch's CPU matmuls go to MKL, which on this AMD CPU runs the weight gradients of the small MLPs
(x^T g over 16k rows) at ~110 GFLOP/s; oneDNN's matmul takes a third of the time. torch routes
float32 matmuls to oneDNN only when `torch.backends.mkldnn.matmul.fp32_precision` allows bf16
arithmetic, and oneDNN then down-converts only on CPUs with bf16 matrix units (AMX); here it
computes in float32. So the setting is switched on only after a probe of this process's product
shapes agrees with float64 to float32 rounding; on a CPU where oneDNN would round through bf16
(errors ~1e-3), it is switched back off. `model/linear.py`'s inner products are exact float32
everywhere and need no probe.
"""
from __future__ import annotations

import os

import torch

# (rows, inner, cols, transposed left operand): a layer, a weight gradient, the SDF row, a pose.
_PROBE_SHAPES = [(4096, 71, 64, False), (64, 4096, 71, True), (4096, 64, 33, False), (33, 4096, 64, True), (256, 3, 3, False)]
_TOLERANCE = 1e-5  # relative to the product's scale: float32 rounding is ~1e-7, bf16 ~1e-3


def probe_errors(seed: int = 0) -> list[float]:
    """Max relative error of float32 matmuls against float64 on `_PROBE_SHAPES`."""
    g = torch.Generator().manual_seed(seed)
    errs = []
    for m, k, n, transposed in _PROBE_SHAPES:
        a = torch.randn(k, m, generator=g).t() if transposed else torch.randn(m, k, generator=g)
        b = torch.randn(k, n, generator=g)
        ref = a.double() @ b.double()
        errs.append(float(((a @ b).double() - ref).abs().max() / ref.abs().max()))
    return errs


def enable_onednn_matmul() -> bool:
    """Route float32 matmuls through oneDNN when they stay float32 here (process-wide; the
    orchestrator calls it once). False, and nothing changed, where oneDNN is missing, where it
    would round through bf16, or with NICER_STREAM_ONEDNN=0."""
    mkldnn = torch.backends.mkldnn
    if os.environ.get("NICER_STREAM_ONEDNN", "1") == "0" or not mkldnn.is_available() or not hasattr(mkldnn, "matmul"):
        return False
    previous = mkldnn.matmul.fp32_precision
    try:
        mkldnn.matmul.fp32_precision = "bf16"
    except (RuntimeError, ValueError, AttributeError):
        return False
    if max(probe_errors()) <= _TOLERANCE:
        return True
    mkldnn.matmul.fp32_precision = previous
    return False
