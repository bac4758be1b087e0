"""Every message of an MCAP file, decoded: how the tests check what the MCAP sink wrote."""
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
