"""Denormal floats flushed to zero while the SLAM's products run (flush-to-zero and
denormals-are-zero on the calling thread and its OpenMP workers, `model/kernels/fpenv.cpp`).

Products of small gradients (a 1e-10 adjoint times a sigmoid of 1e-35) land below float32's
smallest normal (1.2e-38), and x86 CPUs compute with such operands on a microcode path ~100x
slower: one weight-gradient product of the fine MLP took 15 ms instead of 1 (docs/decisions.md).
Flushed, they are 0, an absolute change below 1.2e-38. The setting is per thread and is
scoped (`flush_denormals()`), so code outside the SLAM's optimisation loops (trimesh's rtree,
which crashed with it on) never sees it. NICER_STREAM_FTZ=0 keeps IEEE denormals (the reference);
without the compiled helper, only the calling thread is set (`torch.set_flush_denormal`).
"""
from __future__ import annotations

import contextlib
import os
import threading

import torch

from nicer_stream.model.cpp_kernel import CppKernel

_KERNEL = CppKernel("nicer_stream_fpenv", "fpenv.cpp", ["-O2", "-fopenmp"])
_state = threading.local()  # per thread: the nesting depth of flush_denormals()


def enabled() -> bool:
    """False with NICER_STREAM_FTZ=0 or NICER_STREAM_KERNELS=0."""
    return os.environ.get("NICER_STREAM_FTZ", "1") != "0" and os.environ.get("NICER_STREAM_KERNELS", "1") != "0"


def _helper():
    """The compiled helper, or None where it cannot be built or does not know this CPU."""
    mod = _KERNEL.module()
    return mod if mod is not None and mod.supported() else None


def _set(on: bool) -> None:
    mod = _helper()
    if mod is not None:
        mod.set_flush(on, torch.get_num_threads())
    else:
        torch.set_flush_denormal(on)


@contextlib.contextmanager
def flush_denormals():
    """Within the block, denormal operands and results are 0 on this thread and its OpenMP
    workers; the previous (IEEE) behaviour is restored on exit, also on an exception. Nests."""
    if not enabled():
        yield
        return
    depth = getattr(_state, "depth", 0)
    if depth == 0:
        _set(True)
    _state.depth = depth + 1
    try:
        yield
    finally:
        _state.depth = depth
        if depth == 0:
            _set(False)


if __name__ == "__main__":  # `make setup` builds the helper once, so the first run does not wait for it
    print("fpenv helper:", "built" if _KERNEL.module() is not None else "not available (calling thread only)")
