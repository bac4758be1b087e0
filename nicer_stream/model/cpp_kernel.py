"""Build-on-first-use C++ CPU kernels (`model/kernels/*.cpp`), each with a pure-torch reference.

torch's C++ extension loader compiles a source once (g++ and ninja; ~25 s) and caches it under
~/.cache/torch_extensions, under a name that carries the checkout's path: torch rebuilds a cached
extension whose source path changed, so two checkouts sharing one name rebuilt each other's at
every process start. The grid and activation kernels are built with `-march=native`, so the name
also carries what the compiler resolves that to (the CPU's model and instruction sets, without the
kernel's volatile flags): a cache shared between machines (a network home directory) never loads
a build made for another CPU. It carries the source's bytes, the flags
and torch's version too, so a finished build under that name is the build: it is imported directly.
torch's `load` takes a `lock` file in the build directory on every first use in a process, even to
find the build up to date, and a process killed there (Ctrl-C, a stopped run, a test that kills one)
left it behind: every later process waited on it for ever. `load` now runs only to build.
Where a kernel cannot be built, on a GPU, for other
dtypes, or with NICER_STREAM_KERNELS=0, callers take their reference paths (tests compare both)."""
from __future__ import annotations

import hashlib
import importlib.util
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
    """What a `-march=native` build depends on: the target options the compiler resolves it to
    (`native_target`), else the CPU's model name and flags (`cpuinfo_identity`). Nothing else
    about the machine enters, so the name stays put while the build would not change."""
    return native_target() or cpuinfo_identity()


def native_target(compiler: str | None = None) -> str:
    """The compiler's `-march=native`: its -march / -mtune values and the enabled target options,
    sorted ('' when no compiler answers)."""
    import subprocess

    cmd = [compiler or os.environ.get("CXX", "c++"), "-march=native", "-Q", "--help=target"]
    try:
        text = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return ""
    return target_options(text)


def target_options(help_text: str) -> str:
    """`-Q --help=target` output -> its -march/-mtune values and enabled options, one per line, sorted."""
    keep = set()
    for line in help_text.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0] in ("-march=", "-mtune="):
            keep.add(parts[0] + parts[1])
        elif len(parts) == 2 and parts[0].startswith("-m") and parts[1] == "[enabled]":
            keep.add(parts[0])
    return "\n".join(sorted(keep))


def cpuinfo_identity(text: str | None = None) -> str:
    """The CPU's model name and the flags every core has, sorted (Linux: /proc/cpuinfo), else the
    platform's processor string."""
    if text is None:
        try:
            text = Path("/proc/cpuinfo").read_text()
        except OSError:
            text = ""
    models, flags = set(), None
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "model name":
            models.add(value.strip())
        elif key.strip() == "flags":
            flags = set(value.split()) if flags is None else flags & set(value.split())
    ident = sorted(models) + sorted(flags or ())
    return "\n".join(ident) or f"{platform.machine()} {platform.processor()}"


def build_name(name: str, kernel_dir: Path = KERNEL_DIR, cpu: str | None = None, content: str = "") -> str:
    """The extension's cache name: `name` and a hash of the checkout's kernel directory, of the
    CPU (`cpu_identity()` unless given) and of `content` (what the build is made of)."""
    key = f"{kernel_dir.resolve()}\n{cpu_identity() if cpu is None else cpu}\n{content}"
    return f"{name}_{hashlib.sha1(key.encode()).hexdigest()[:8]}"


def build_content(source: Path, cflags: list[str]) -> str:
    """What a build is made of: the source's bytes (hashed), the flags and torch's version. A
    missing source gives a name all the same (its build then fails and callers take the reference)."""
    try:
        digest = hashlib.sha1(source.read_bytes()).hexdigest()
    except OSError:
        digest = "missing"
    return f"{digest}\n{' '.join(cflags)}\n{torch.__version__}"


class CppKernel:
    """One source file under `kernels/`, compiled with `cflags` when first asked for."""

    def __init__(self, name: str, source: str, cflags: list[str]) -> None:
        self.source, self.cflags = KERNEL_DIR / source, cflags
        self.name = build_name(name, content=build_content(self.source, cflags))
        self._module = None
        self._failed = False

    def module(self):
        """The compiled module, or None when it cannot be built (warned once)."""
        if self._module is None and not self._failed:
            self._module = self._import_built()
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

    def _build_dir(self) -> Path | None:
        """torch's cache directory for this name, or None when it cannot be told
        (`_get_build_directory` is torch's private helper)."""
        try:
            from torch.utils.cpp_extension import _get_build_directory

            return Path(_get_build_directory(self.name, False))
        except Exception:
            return None

    def _library(self) -> Path | None:
        """The finished build's shared library under this name, if torch's cache holds one."""
        d = self._build_dir()
        lib = None if d is None else d / f"{self.name}.so"
        return lib if lib is not None and lib.is_file() and lib.stat().st_size > 0 else None

    def _import_built(self):
        """The finished build imported without torch's `load` (and its lock), or None (then `load`)."""
        lib = self._library()
        if lib is None:
            return None
        try:
            spec = importlib.util.spec_from_file_location(self.name, lib)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            return mod
        except Exception:  # a truncated or foreign file: let torch's `load` rebuild it
            return None

    def _built_before(self) -> bool:
        """Whether torch's cache already holds a build of this name (True when that cannot be
        told: the message is only a nicety that must never take the compiled path away)."""
        d = self._build_dir()
        return d is None or any(d.glob("*.so"))

    def available(self, t: torch.Tensor) -> bool:
        """True when `t` can go through the compiled kernel (CPU, float32/float64, enabled, built)."""
        if t.device.type != "cpu" or t.dtype not in (torch.float32, torch.float64):
            return False
        if os.environ.get("NICER_STREAM_KERNELS", "1") == "0":
            return False
        return self.module() is not None
