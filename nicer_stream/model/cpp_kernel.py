"""Build-on-first-use C++ CPU kernels (`model/kernels/*.cpp`), each with a pure-torch reference.

torch's C++ extension loader compiles a source once (g++ and ninja; ~25 s) and caches it under
~/.cache/torch_extensions, under a name that carries the checkout's path: torch rebuilds a cached
extension whose source path changed, so two checkouts sharing one name rebuilt each other's at
every process start. (A build killed midway still leaves a `lock` file there that the next build
of the same checkout waits on: delete it.) The grid and activation kernels are built with
`-march=native`, so the name also carries the CPU's model and instruction-set flags: a cache
shared between machines (a network home directory) never loads a build made for another CPU.
Where a kernel cannot be built, on a GPU, for other
dtypes, or with NICER_STREAM_KERNELS=0, callers take their reference paths (tests compare both)."""
from __future__ import annotations

import hashlib
import logging
import os
import platform
import sys
from functools import lru_cache
from pathlib import Path

import torch

log = logging.getLogger(__name__)
KERNEL_DIR = Path(__file__).parent / "kernels"


@lru_cache(maxsize=1)
def cpu_identity() -> str:
    """The CPU's model name and instruction-set flags (Linux: /proc/cpuinfo), else the platform's
    processor string: what a `-march=native` build depends on."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        lines = []
    keep = [ln.split(":", 1)[1].strip() for ln in lines if ln.split(":", 1)[0].strip() in ("model name", "flags")]
    return "\n".join(dict.fromkeys(keep)) or f"{platform.machine()} {platform.processor()}"


def build_name(name: str, kernel_dir: Path = KERNEL_DIR, cpu: str | None = None) -> str:
    """The extension's cache name: `name` and a hash of the checkout's kernel directory and of the
    CPU (`cpu_identity()` unless given)."""
    key = f"{kernel_dir.resolve()}\n{cpu_identity() if cpu is None else cpu}"
    return f"{name}_{hashlib.sha1(key.encode()).hexdigest()[:8]}"


class CppKernel:
    """One source file under `kernels/`, compiled with `cflags` when first asked for."""

    def __init__(self, name: str, source: str, cflags: list[str]) -> None:
        self.name, self.source, self.cflags = build_name(name), KERNEL_DIR / source, cflags
        self._module = None
        self._failed = False

    def module(self):
        """The compiled module, or None when it cannot be built (warned once)."""
        if self._module is None and not self._failed:
            if not self._built_before():
                # ~30 s of g++ with nothing else printed: say why the run waits
                print(f"compiling {self.source.name} for this CPU (once per checkout and CPU, ~30 s)",
                      file=sys.stderr, flush=True)
            try:
                from torch.utils.cpp_extension import load

                self._module = load(name=self.name, sources=[str(self.source)], extra_cflags=self.cflags,
                                    extra_ldflags=["-fopenmp"], verbose=False)
            except Exception as e:  # no compiler, no ninja, ...: the reference path still works
                self._failed = True
                log.warning("%s not built (%s): using the slower pure-torch path", self.source.name,
                            str(e).splitlines()[0][:200])
        return self._module

    def _built_before(self) -> bool:
        """Whether torch's cache already holds a build of this name (True when that cannot be
        told: `_get_build_directory` is torch's private helper, and the message is only a nicety
        that must never take the compiled path away)."""
        try:
            from torch.utils.cpp_extension import _get_build_directory

            return any(Path(_get_build_directory(self.name, False)).glob("*.so"))
        except Exception:
            return True

    def available(self, t: torch.Tensor) -> bool:
        """True when `t` can go through the compiled kernel (CPU, float32/float64, enabled, built)."""
        if t.device.type != "cpu" or t.dtype not in (torch.float32, torch.float64):
            return False
        if os.environ.get("NICER_STREAM_KERNELS", "1") == "0":
            return False
        return self.module() is not None
