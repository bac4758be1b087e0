"""Reading our recordings back: every message of an MCAP file, every column of a .rrd file.
Used by `convert`/`inspect`-style tools and by the tests that check what the sinks wrote."""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path


def read_mcap(path: str | Path) -> dict[str, list]:
    """topic -> [(log_time ns, decoded protobuf message)] in file order."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        for _, ch, msg, dec in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            out[ch.topic].append((msg.log_time, dec))
    return out


def read_rrd_columns(path: str | Path) -> dict[str, dict[str, list]]:
    """entity path -> column name -> values of all rows (timestamps as int64 ns)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    out: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    for ch in RrdReader(path).stream():
        rb = ch.to_record_batch()
        for name in rb.schema.names:
            col = rb.column(name)
            if pa.types.is_timestamp(col.type):
                col = col.cast(pa.int64())
            out[ch.entity_path][name].extend(col.to_pylist())
    return out
