"""The compiled kernels' cache names: one per checkout, stable within it."""
from pathlib import Path

from nicer_stream.model.cpp_kernel import KERNEL_DIR, build_name


def test_build_name_is_stable_and_differs_between_checkouts(tmp_path):
    assert build_name("k") == build_name("k", KERNEL_DIR)
    assert build_name("k", tmp_path / "a") != build_name("k", tmp_path / "b")
    assert build_name("k").startswith("k_") and build_name("k").isidentifier()  # a valid module name


def test_build_name_resolves_links(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    assert build_name("k", tmp_path / "link") == build_name("k", Path(tmp_path / "real"))
