"""The compiled kernels' cache names (one per checkout, CPU and build content, stable within them) and loading."""
from pathlib import Path

from nicer_stream.model.cpp_kernel import KERNEL_DIR, build_name, cpu_identity


def test_build_name_is_stable_and_differs_between_checkouts(tmp_path):
    assert build_name("k") == build_name("k", KERNEL_DIR)
    assert build_name("k", tmp_path / "a") != build_name("k", tmp_path / "b")
    assert build_name("k").startswith("k_") and build_name("k").isidentifier()  # a valid module name


def test_build_name_resolves_links(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    assert build_name("k", tmp_path / "link") == build_name("k", Path(tmp_path / "real"))


def test_build_name_differs_between_cpus():
    # -march=native builds: a cache shared by two machines must not hand one CPU's build to the other
    assert build_name("k", cpu="AMD EPYC\nfma avx avx2") != build_name("k", cpu="Intel Xeon\nfma avx avx2 avx512f")
    assert build_name("k", cpu=cpu_identity()) == build_name("k")
    assert cpu_identity()  # something identifies this CPU


def test_a_first_build_says_why_the_run_waits(tmp_path, monkeypatch, capsys):
    import torch.utils.cpp_extension as ext

    from nicer_stream.model.cpp_kernel import CppKernel

    monkeypatch.setenv("TORCH_EXTENSIONS_DIR", str(tmp_path))
    monkeypatch.setattr(ext, "load", lambda **kw: "module")  # no compiler run here
    k = CppKernel("test_kernel", "grid_interp.cpp", [])
    assert k.module() == "module"
    assert "compiling grid_interp.cpp for this CPU" in capsys.readouterr().err
    built = Path(ext._get_build_directory(k.name, False))
    (built / f"{k.name}.so").write_bytes(b"")  # as a finished build leaves it
    assert CppKernel("test_kernel", "grid_interp.cpp", []).module() == "module"
    assert capsys.readouterr().err == ""  # cached: nothing to say
    monkeypatch.delattr(ext, "_get_build_directory")  # torch's private helper gone: still built, no message
    assert CppKernel("test_kernel_2", "grid_interp.cpp", []).module() == "module"
    assert capsys.readouterr().err == ""


def test_a_finished_build_is_imported_past_a_stale_lock(monkeypatch):
    """A process killed inside torch's `load` leaves `lock` in the build directory; every later
    `load` waited on it for ever. A finished build is imported without `load`."""
    import torch
    import torch.utils.cpp_extension as ext

    from nicer_stream.model.cpp_kernel import CppKernel
    from nicer_stream.model.positional import ENCODING_KERNEL

    if ENCODING_KERNEL.module() is None:
        import pytest
        pytest.skip("the encoding kernel could not be built here")
    built = Path(ext._get_build_directory(ENCODING_KERNEL.name, False))
    lock = built / "lock"
    lock.touch()
    try:
        def no_load(**kw):
            raise AssertionError("torch's load (and its lock) must not be reached for a finished build")

        monkeypatch.setattr(ext, "load", no_load)
        fresh = CppKernel("nicer_stream_encoding", "encoding.cpp", ENCODING_KERNEL.cflags)
        assert fresh.name == ENCODING_KERNEL.name
        enc = fresh.module().positional_encode(torch.zeros(2, 3), torch.ones(1))
        assert enc.shape == (2, 9)
    finally:
        lock.unlink()


def test_the_name_changes_with_the_source_and_the_flags(tmp_path):
    from nicer_stream.model.cpp_kernel import build_content

    src = tmp_path / "k.cpp"
    src.write_text("int a;")
    one = build_name("k", content=build_content(src, ["-O3"]))
    assert one == build_name("k", content=build_content(src, ["-O3"]))
    assert one != build_name("k", content=build_content(src, ["-O2"]))
    src.write_text("int b;")
    assert one != build_name("k", content=build_content(src, ["-O3"]))


def test_a_missing_source_gives_the_reference_path_not_an_import_error(tmp_path, monkeypatch):
    from nicer_stream.model.cpp_kernel import CppKernel

    monkeypatch.setenv("TORCH_EXTENSIONS_DIR", str(tmp_path))
    k = CppKernel("test_missing", "no_such_kernel.cpp", [])  # the constructor runs at import time
    assert k.module() is None


def test_the_cpu_identity_ignores_flag_order_and_a_flag_only_one_core_has():
    from nicer_stream.model.cpp_kernel import cpuinfo_identity, target_options

    a = "model name\t: AMD EPYC\nflags\t\t: fpu sse avx avx2 hypervisor\nmodel name\t: AMD EPYC\nflags\t\t: avx2 avx fpu sse\n"
    b = "model name\t: AMD EPYC\nflags\t\t: sse fpu avx2 avx\n"
    assert cpuinfo_identity(a) == cpuinfo_identity(b) and "avx2" in cpuinfo_identity(a)
    assert cpuinfo_identity(b) != cpuinfo_identity(b.replace(" avx2", ""))
    gcc = "  -march=                     \tznver3\n  -mavx2                      \t[enabled]\n  -mavx512f                   \t[disabled]\n"
    assert target_options(gcc) == "-march=znver3\n-mavx2"


def test_the_kernel_names_are_the_same_in_every_process_of_a_checkout(tmp_path):
    """Two processes, other working directories and thread settings: the same four names."""
    import os
    import subprocess
    import sys

    code = ("from nicer_stream.model import grid_kernel, positional, softplus; from nicer_stream import denormals;"
            "print(grid_kernel._KERNEL.name, positional.ENCODING_KERNEL.name, softplus.SOFTPLUS_KERNEL.name, denormals._KERNEL.name)")
    root = str(Path(__file__).resolve().parents[3])
    names = []
    for cwd, threads in ((tmp_path, "1"), (root, "2")):
        env = {**os.environ, "PYTHONPATH": root, "OMP_NUM_THREADS": threads}
        names.append(subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, capture_output=True, text=True,
                                    check=True).stdout.split())
    assert names[0] == names[1] and len(names[0]) == 4
