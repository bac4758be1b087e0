"""Frame sources addressed by URI: `scheme:PATH[?key=value&...]`.

Each scheme maps to a module exposing `open(path, query, opts) -> FrameSource`.
"""
from __future__ import annotations

import importlib
from urllib.parse import parse_qsl

from nicer_stream.errors import SourceError
from sources.base import FrameSource, SourceOptions

SCHEMES = {
    "replica": "sources.replica",
    "tum": "sources.tum",
    "7scenes": "sources.sevenscenes",
    "folder": "sources.folder",
    "synthetic": "sources.synthetic",
    "video": "sources.video",
    "mcap": "sources.mcap_source",
}


def parse_uri(uri: str) -> tuple[str, str, dict[str, str]]:
    """'scheme:path?k=v' -> (scheme, path, {k: v})."""
    if ":" not in uri:
        raise SourceError(f"source '{uri}' has no scheme: use one of {', '.join(s + ':PATH' for s in SCHEMES)}")
    scheme, rest = uri.split(":", 1)
    path, _, q = rest.partition("?")
    return scheme, path, dict(parse_qsl(q, keep_blank_values=True))


def open_source(uri: str, opts: SourceOptions | None = None) -> FrameSource:
    """Open the source named by `uri` with shared options `opts`."""
    scheme, path, query = parse_uri(uri)
    if scheme not in SCHEMES:
        raise SourceError(f"unknown source scheme '{scheme}': use one of {', '.join(SCHEMES)}")
    module = importlib.import_module(SCHEMES[scheme])
    src = module.open(path, query, opts or SourceOptions())
    src.uri = uri
    return src
