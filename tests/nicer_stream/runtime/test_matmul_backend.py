"""enable_onednn_matmul: on only where the probe stays float32, off with a bf16-rounding CPU and
with NICER_STREAM_ONEDNN=0."""
import torch

from nicer_stream.runtime import matmul_backend
from nicer_stream.runtime.matmul_backend import enable_onednn_matmul, probe_errors


def _restore(previous: str) -> None:
    torch.backends.mkldnn.matmul.fp32_precision = previous


def test_enabled_only_when_the_products_stay_float32():
    previous = torch.backends.mkldnn.matmul.fp32_precision
    try:
        on = enable_onednn_matmul()
        errs = probe_errors(seed=1)  # with whatever the call left in place
        assert max(errs) < 1e-5  # never worse than float32 rounding afterwards
        assert on == (torch.backends.mkldnn.matmul.fp32_precision == "bf16")
    finally:
        _restore(previous)


def test_a_cpu_that_rounds_through_bf16_keeps_the_default(monkeypatch):
    previous = torch.backends.mkldnn.matmul.fp32_precision
    monkeypatch.setattr(matmul_backend, "probe_errors", lambda seed=0: [3e-3])  # what bf16 gives
    try:
        assert not enable_onednn_matmul()
        assert torch.backends.mkldnn.matmul.fp32_precision == previous
    finally:
        _restore(previous)


def test_disabled_by_environment(monkeypatch):
    previous = torch.backends.mkldnn.matmul.fp32_precision
    monkeypatch.setenv("NICER_STREAM_ONEDNN", "0")
    assert not enable_onednn_matmul()
    assert torch.backends.mkldnn.matmul.fp32_precision == previous


def test_probe_detects_bf16_rounding():
    """The probe's tolerance separates float32 from bf16 products (emulated by rounding the inputs)."""
    a, b = torch.randn(512, 71), torch.randn(71, 64)
    ref = a.double() @ b.double()
    bf = (a.bfloat16().float() @ b.bfloat16().float()).double()
    assert float((bf - ref).abs().max() / ref.abs().max()) > matmul_backend._TOLERANCE
