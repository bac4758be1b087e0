"""On-disk prior cache: one file per frame / per flow pair, written by `nicer-stream priors`.

Format (format_version 1), in a directory DIR:
- DIR/meta.json: {"format_version": 1, "depth_normal_provider": str, "flow_provider": str,
  "width": int, "height": int, "source": str (informational)}.
- DIR/depth_normal/frame_NNNNNN.npz: arrays `depth` (H, W) float32 relative depth and
  `normal` (H, W, 3) float32 unit camera-frame normals (OpenCV axes, facing the camera);
  a key is absent when the provider gave None.
- DIR/flow/flow_SSSSSS_DDDDDD.npz: `flow` (H, W, 2) float32 (du, dv) pixels from frame
  SSSSSS to frame DDDDDD and `valid` (H, W) bool.
NNNNNN, SSSSSS, DDDDDD are `Frame.index` zero-padded to 6 digits, so a cache is
read with the same source and the same --start/--stride/--max-side it was written with.
"""
from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from nicer_stream.errors import UserError
from nicer_stream.priors.base import DepthNormal, DepthNormalProvider, FlowProvider
from nicer_stream.types import FlowPrior, Frame

FORMAT_VERSION = 1
_HOW = "create it with `nicer-stream priors --source URI --provider NAME --out {dir}` (same source options)"


@dataclass(frozen=True)
class CacheMeta:
    """Contents of DIR/meta.json."""

    format_version: int
    depth_normal_provider: str
    flow_provider: str
    width: int
    height: int
    source: str = ""


def depth_normal_path(root: Path, index: int) -> Path:
    return Path(root) / "depth_normal" / f"frame_{index:06d}.npz"


def flow_path(root: Path, src: int, dst: int) -> Path:
    return Path(root) / "flow" / f"flow_{src:06d}_{dst:06d}.npz"


def read_meta(root: Path) -> CacheMeta:
    """Read and check DIR/meta.json; UserError if missing, unreadable or of another version."""
    path = Path(root) / "meta.json"
    if not path.is_file():
        raise UserError(f"{root} is not a prior cache (no {path}): {_HOW.format(dir=root)}")
    try:
        meta = CacheMeta(**json.loads(path.read_text()))
    except (ValueError, TypeError) as e:
        raise UserError(f"{path} is not a valid prior-cache meta.json ({e}): recreate the cache") from None
    if meta.format_version != FORMAT_VERSION:
        raise UserError(f"{path} has format_version {meta.format_version}, this build reads {FORMAT_VERSION}: recreate the cache")
    return meta


class CacheWriter:
    """Writes a prior cache (see the module docstring); meta.json is written on creation."""

    def __init__(self, root: Path, meta: CacheMeta) -> None:
        self.root = Path(root)
        self.meta = meta
        (self.root / "depth_normal").mkdir(parents=True, exist_ok=True)
        (self.root / "flow").mkdir(parents=True, exist_ok=True)
        (self.root / "meta.json").write_text(json.dumps(asdict(meta), indent=2) + "\n")

    def write_depth_normal(self, index: int, dn: DepthNormal) -> Path:
        arrays = {k: np.asarray(v, np.float32) for k, v in (("depth", dn.depth), ("normal", dn.normal)) if v is not None}
        path = depth_normal_path(self.root, index)
        np.savez_compressed(path, **arrays)
        return path

    def write_flow(self, f: FlowPrior) -> Path:
        path = flow_path(self.root, f.src_index, f.dst_index)
        np.savez_compressed(path, flow=np.asarray(f.flow, np.float32), valid=np.asarray(f.valid, bool))
        return path


def _load(path: Path, root: Path, extra: str = "") -> dict[str, np.ndarray]:
    if not path.is_file():
        raise UserError(f"prior cache file {path} is missing: {_HOW.format(dir=root)}{extra}")
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _check_size(meta: CacheMeta, frame: Frame, root: Path) -> None:
    if (frame.width, frame.height) != (meta.width, meta.height):
        raise UserError(
            f"prior cache {root} holds {meta.width}x{meta.height} images but frame {frame.index} is "
            f"{frame.width}x{frame.height}: use the --max-side the cache was written with"
        )


class CacheDepthNormal(DepthNormalProvider):
    """`cache:DIR` depth/normal provider; named 'cache(<writer's provider>)' so an oracle cache stays labelled."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.meta = read_meta(self.root)
        self.name = f"cache({self.meta.depth_normal_provider})"

    def predict(self, frame: Frame) -> DepthNormal:
        _check_size(self.meta, frame, self.root)
        z = _load(depth_normal_path(self.root, frame.index), self.root)
        return DepthNormal(depth=z.get("depth"), normal=z.get("normal"))


class CacheFlow(FlowProvider):
    """`cache:DIR` flow provider reading DIR/flow/flow_SSSSSS_DDDDDD.npz."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.meta = read_meta(self.root)
        self.name = f"cache({self.meta.flow_provider})"

    def has(self, src: Frame, dst: Frame) -> bool:
        return flow_path(self.root, src.index, dst.index).is_file() and flow_path(self.root, dst.index, src.index).is_file()

    def flow(self, src: Frame, dst: Frame) -> FlowPrior:
        _check_size(self.meta, src, self.root)
        gap = abs(dst.index - src.index)
        z = _load(flow_path(self.root, src.index, dst.index), self.root, f" with --flow-gap {gap} or more")
        return FlowPrior(src.index, dst.index, z["flow"], z["valid"])
