"""retain_freed_memory: the large temporaries of an iteration reuse freed pages instead of
page-faulting fresh ones in."""
import resource
import subprocess
import sys

import pytest

_CHILD = """
import resource, sys
import torch
from nicer_stream.runtime.allocator import retain_freed_memory
if sys.argv[1] == "retain":
    assert retain_freed_memory()
# Above glibc's largest adaptive mmap threshold (32 MB), so that by default every such tensor is
# a fresh mmap whatever the heap's history (smaller ones may or may not be: it adapts).
z = torch.randn(5 * 32640, 64)  # five mapping iterations' hidden activations: 42 MB each
def cycle():  # temporaries of the kind softplus makes, each freed before the next
    return (torch.exp(-z.abs()) + 1).log() + z.relu()
for _ in range(3):  # the heap reaches its working size
    cycle()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):
    cycle()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def _faults(mode: str) -> int:
    out = subprocess.run([sys.executable, "-c", _CHILD, mode], capture_output=True, text=True, check=True)
    return int(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_freed_large_temporaries_are_reused_without_page_faults():
    pages = (5 * 32640 * 64 * 4) // resource.getpagesize()  # one tensor
    default, retained = _faults("default"), _faults("retain")
    assert default > 3 * pages  # glibc unmaps freed 42 MB tensors: the cycles fault them in again
    # Retained: none, or a late growth of the heap by a tensor or two (0 or 10,200 faults here,
    # against 714,070 by default).
    assert retained <= 3 * pages and retained < default / 20
