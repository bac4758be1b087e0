"""`mcap:FILE[?topic=NAME]`: camera images from an MCAP log (Foxglove protobuf or ROS 2).

The camera topic is the only colour image topic, or `?topic=`; its calibration topic
is paired by namespace / frame_id (sources.mcap_calibration.pair_calibration_topic);
`--intrinsics` overrides it. Timestamps are the sensor stamps (header.stamp /
timestamp), `Frame.timestamp_ns` holds them exactly. Distorted images are undistorted
to a pinhole camera without invalid border (sources.undistort), whose K the frames
carry. Messages are streamed one at a time, never all loaded.
Indexed files are read chunk by chunk in log-time order; index-less or truncated files
are read linearly from the start, in file order.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

from mcap.reader import NonSeekingReader, make_reader
from mcap.records import Channel, Schema
from mcap.stream_reader import StreamReader
from mcap_protobuf.decoder import DecoderFactory as ProtobufDecoderFactory
from mcap_ros2.decoder import DecoderFactory as Ros2DecoderFactory

from nicer_stream.errors import SourceError
from nicer_stream.types import Frame
from sources.base import FrameSource, SourceOptions
from sources.intrinsics_files import MISSING_HINT
from sources.mcap_calibration import (
    CALIBRATION_SCHEMAS, calibration_from_flag, calibration_from_message, pair_calibration_topic,
)
from sources.mcap_images import IMAGE_SCHEMAS, CorruptImage, decode_image, frame_id, image_kind, stamp_ns
from sources.undistort import CameraCalibration, Undistorter

log = logging.getLogger(__name__)
MAGIC = b"\x89MCAP0\r\n"


@dataclass(frozen=True)
class McapLayout:
    """What an MCAP file holds. topics: topic -> schema name ('' if none)."""

    path: Path
    topics: dict[str, str]
    indexed: bool
    """Summary with chunk indexes: read by seeking, chunk by chunk."""
    complete: bool
    """Ends with the MCAP magic; False for a truncated file."""
    counts: dict[str, int] = field(default_factory=dict)
    """Messages per topic from the summary's statistics (indexed, complete files; else empty)."""

    def listing(self, names=None) -> str:
        names = sorted(self.topics) if names is None else names
        return ", ".join(f"{t} ({self.topics[t] or 'no schema'})" for t in names) or "none"


def read_layout(path: Path) -> McapLayout:
    """Topics and index state of an MCAP file. Raises SourceError if it is not an MCAP file."""
    with path.open("rb") as f:
        if f.read(len(MAGIC)) != MAGIC:
            raise SourceError(f"{path} is not an MCAP file (bad magic bytes): give a .mcap recording")
        f.seek(0, 2)
        complete = f.tell() >= 2 * len(MAGIC) and _tail(f) == MAGIC
        summary = None
        if complete:
            try:
                f.seek(0)  # the reader checks the magic where the stream is
                summary = make_reader(f).get_summary()
            except Exception:  # a damaged summary: fall back to scanning
                summary = None
        if summary is not None and summary.channels:
            names = {i: s.name for i, s in summary.schemas.items()}
            topics = {c.topic: names.get(c.schema_id, "") for c in summary.channels.values()}
            stats = summary.statistics.channel_message_counts if summary.statistics is not None else {}
            ids = {t: [i for i, c in summary.channels.items() if c.topic == t] for t in topics}
            counts = {t: sum(stats[i] for i in ids[t]) for t in topics if all(i in stats for i in ids[t])}
            return McapLayout(path, topics, bool(summary.chunk_indexes), complete, counts)
        # No summary: the channel records are spread through the data section.
        f.seek(0)
        names, topics = {}, {}
        try:
            for rec in StreamReader(f).records:
                if isinstance(rec, Schema):
                    names[rec.id] = rec.name
                elif isinstance(rec, Channel):
                    topics[rec.topic] = names.get(rec.schema_id, "")
        except Exception:
            complete = False
        return McapLayout(path, topics, False, complete)


def _tail(f) -> bytes:
    f.seek(-len(MAGIC), 2)
    return f.read(len(MAGIC))


def iter_decoded(f, layout: McapLayout, topics: list[str]) -> Iterator[tuple[str, str, object | Exception, int]]:
    """Yield (topic, schema name, decoded message or the decode error, log_time ns).

    Decoding is per message (not iter_decoded_messages) so that one corrupt payload
    is skippable. Errors from the file itself (truncation) propagate.
    """
    factories = [ProtobufDecoderFactory(), Ros2DecoderFactory()]
    if layout.indexed:
        # Log-time order makes the seeking reader load one chunk at a time.
        messages = make_reader(f, decoder_factories=factories).iter_messages(topics=topics, log_time_order=True)
    else:
        # File order: log-time order would make this reader sort (load) everything.
        messages = NonSeekingReader(f, decoder_factories=factories).iter_messages(topics=topics, log_time_order=False)
    decoders: dict[int, object] = {}
    for schema, channel, message in messages:
        if channel.id not in decoders:
            decoders[channel.id] = _decoder(factories, channel, schema)
        decoder, name = decoders[channel.id], schema.name if schema else ""
        try:
            if decoder is None:
                raise ValueError(f"no decoder for {channel.message_encoding} / {name}")
            decoded = decoder(message.data)
        except Exception as e:
            decoded = e
        yield channel.topic, name, decoded, message.log_time


def _decoder(factories, channel: Channel, schema: Schema | None):
    """The first factory's decoder for this channel, or None (also for an unparsable schema)."""
    for factory in factories:
        try:
            decoder = factory.decoder_for(channel.message_encoding, schema)
        except Exception:
            decoder = None
        if decoder is not None:
            return decoder
    return None


def first_messages(layout: McapLayout, topics: list[str]) -> dict[str, object]:
    """First successfully decoded message of each topic (stops reading once all are seen)."""
    found: dict[str, object] = {}
    with layout.path.open("rb") as f:
        try:
            for topic, _, decoded, _ in iter_decoded(f, layout, topics):
                if topic not in found and not isinstance(decoded, Exception):
                    found[topic] = decoded
                    if len(found) == len(topics):
                        break
        except Exception:  # truncated: keep what was readable
            pass
    return found


def choose_image_topic(layout: McapLayout, requested: str | None, firsts: dict[str, object]) -> str:
    """The camera topic: `requested`, or the only colour image topic. Raises SourceError."""
    images = sorted(t for t, s in layout.topics.items() if s in IMAGE_SCHEMAS)
    kinds = {t: image_kind(firsts[t], layout.topics[t]) if t in firsts else "no messages" for t in images}
    colour = [t for t in images if kinds[t] == "color"]
    p = layout.path
    if requested:
        if requested not in images:
            raise SourceError(f"topic {requested} is not an image topic in {p}; image topics: {layout.listing(images)}")
        if kinds[requested] != "color":
            raise SourceError(f"topic {requested} in {p} is not a colour camera ({kinds[requested]}); image topics: {layout.listing(images)}")
        return requested
    if len(colour) == 1:
        return colour[0]
    if not colour:
        extra = f" (not colour: {', '.join(f'{t} {kinds[t]}' for t in images)})" if images else ""
        cut = "" if layout.complete else " (the file is truncated before any image topic)"
        raise SourceError(f"no image topic in {p}; topics: {layout.listing()}{extra}{cut}")
    raise SourceError(f"{p} has several image topics: {layout.listing(colour)}; choose one with mcap:{p}?topic=NAME")


class McapSource(FrameSource):
    """Frames of one image topic of an MCAP file (see module docstring)."""

    def __init__(self, layout: McapLayout, topic: str, calib: CameraCalibration, opts: SourceOptions) -> None:
        super().__init__(opts)
        self.layout, self.topic, self.calibration = layout, topic, calib
        self.schema = layout.topics[topic]
        self.name = f"{layout.path.stem}{topic}"
        self.undistort = Undistorter(calib, enabled=opts.undistort)
        self.truncated = False

    def _frames(self) -> Iterator[Frame]:
        self.skipped_frames, raw, kept, warned_stamp, ended = 0, -1, 0, False, False
        with self.layout.path.open("rb") as f:
            messages = iter_decoded(f, self.layout, [self.topic])
            while self.opts.max_frames is None or kept < self.opts.max_frames:
                try:
                    _, schema, msg, log_time = next(messages)
                except StopIteration:
                    ended = True
                    break
                except Exception as e:  # the file ends mid-record: keep what was read
                    self.truncated = ended = True
                    log.debug("MCAP read stopped: %r", e)
                    break
                raw += 1
                if not self.opts.keeps(raw):
                    continue
                try:
                    if isinstance(msg, Exception):
                        raise CorruptImage(str(msg))
                    rgb = decode_image(msg, schema)
                except CorruptImage as e:
                    self.skipped_frames += 1
                    log.warning("skipping corrupt frame %d of %s in %s: %s", raw, self.topic, self.layout.path, e)
                    continue
                ns = stamp_ns(msg, schema)
                if ns == 0:
                    ns = log_time  # unset sensor stamp: log time is the best we have
                    if not warned_stamp:
                        log.warning("%s in %s has no sensor stamps: using log times", self.topic, self.layout.path)
                        warned_stamp = True
                rgb = self.undistort(rgb)
                h, w = rgb.shape[:2]
                yield Frame(index=kept, timestamp=ns * 1e-9, rgb=rgb, intrinsics=self.undistort.intrinsics(w, h),
                            name=f"{self.topic}#{raw}", timestamp_ns=ns)
                kept += 1
        self._report(kept, ended)  # only when the iteration ends, not when the consumer stops early

    def expected_frames(self) -> int | None:
        """The topic's message count from the summary's statistics, after start/stride/drop/
        max_frames; None for a file without them (index-less, truncated)."""
        if not self.layout.indexed or self.topic not in self.layout.counts:
            return None
        return len(self.opts.selected(self.layout.counts[self.topic]))

    def _report(self, kept: int, ended: bool) -> None:
        if self.skipped_frames:
            log.warning("%s: skipped %d corrupt frame(s) of %s", self.layout.path, self.skipped_frames, self.topic)
        if ended and (self.truncated or not self.layout.complete):
            log.warning("%s is truncated (no MCAP end marker): read %d frame(s) of %s up to the cut; "
                        "re-record or repair it (e.g. `mcap recover`) for the rest", self.layout.path, kept, self.topic)


def open(path: str, query: dict[str, str], opts: SourceOptions) -> McapSource:
    """Open `mcap:path[?topic=NAME]`. Raises SourceError with what to do."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise SourceError(f"MCAP file {path} not found{' (it is a directory)' if p.is_dir() else ''}: check the path")
    try:
        layout = read_layout(p)
    except OSError as e:
        raise SourceError(f"cannot read {path} ({e.strerror or e}): check its permissions") from None
    calib_topics = sorted(t for t, s in layout.topics.items() if s in CALIBRATION_SCHEMAS)
    requested = query.get("topic") or None
    images = [t for t, s in layout.topics.items() if s in IMAGE_SCHEMAS]
    firsts = first_messages(layout, ([requested] if requested in images else images) + calib_topics)
    topic = choose_image_topic(layout, requested, firsts)
    if opts.intrinsics is not None:
        calib = calibration_from_flag(opts.intrinsics)
    else:
        ctopic = pair_calibration_topic(topic, frame_id(firsts[topic], layout.topics[topic]),
                                        {t: frame_id(firsts[t], layout.topics[t]) for t in calib_topics if t in firsts})
        calib = calibration_from_message(firsts[ctopic], layout.topics[ctopic], f"{path}{ctopic}") if ctopic else None
        if calib is None:
            why = f"calibration topics: {layout.listing(calib_topics)}" if calib_topics else "it has no calibration topic"
            raise SourceError(f"no camera calibration for {topic} in {path} ({why}): {MISSING_HINT}")
    return McapSource(layout, topic, calib, opts)
