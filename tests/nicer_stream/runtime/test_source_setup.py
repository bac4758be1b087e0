"""Opening a source as a run does: the preset's image size, and the frontend's larger grey copy."""
from dataclasses import replace

from nicer_stream.config import fast, paper
from nicer_stream.runtime.source_setup import open_configured
from sources.base import SourceOptions


def test_the_frontend_gets_the_sources_larger_image_only_when_a_frontend_runs(replica_dir):
    """`fast` (classical frontend): the map's frames at 320 px carry the 1200 x 680 original as
    grey; `paper` (no frontend), `[frontend] max_side` unset and a run that does not track carry
    none; an explicit
    --max-side still sizes the map's frames."""
    uri = f"replica:{replica_dir}"
    src, opts = open_configured(uri, SourceOptions(max_frames=1), fast())
    f = next(iter(src))
    assert opts.max_side == 320 and opts.detail_side == 1280
    assert f.rgb.shape == (181, 320, 3) and f.detail.grey.shape == (680, 1200)
    assert f.detail.intrinsics.fx == f.intrinsics.fx * 1200 / 320
    cfg = fast()
    for c in (paper(), replace(cfg, frontend=replace(cfg.frontend, max_side=None))):
        src, opts = open_configured(uri, SourceOptions(max_frames=1), c)
        assert opts.detail_side is None and next(iter(src)).detail is None
    src, opts = open_configured(uri, SourceOptions(max_frames=1), cfg, tracking=False)  # `map`: known poses
    assert opts.detail_side is None and next(iter(src)).detail is None
    src, _ = open_configured(uri, SourceOptions(max_frames=1, max_side=160), fast())
    f = next(iter(src))
    assert f.rgb.shape[1] == 160 and f.detail.grey.shape == (680, 1200)
