"""Reading a Rerun recording back, every column of a .rrd file: `convert` turns a run's recording
into MCAP with it, and the tests check what the Rerun sink wrote."""
from __future__ import annotations

from collections import defaultdict
from pathlib import Path


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
