"""Decode MCAP image messages into (H, W, 3) float32 RGB in [0, 1].

Schemas: `foxglove.RawImage`, `foxglove.CompressedImage` (protobuf) and ROS 2
`sensor_msgs/msg/Image`, `sensor_msgs/msg/CompressedImage`.
Raw encodings: rgb8, bgr8, rgba8, bgra8, mono8 (8UC1/8UC3/8UC4 as ROS's mono8/bgr8/bgra8);
rows may be padded (`step` > width * channels). Depth encodings (16UC1, 32FC1, ...) and
`compressedDepth` are depth, not camera images. Compressed: anything cv2.imdecode reads
(jpeg, png, webp), whatever the `format` string says.
"""
from __future__ import annotations

import cv2
import numpy as np

RAW_SCHEMAS = ("foxglove.RawImage", "sensor_msgs/msg/Image")
COMPRESSED_SCHEMAS = ("foxglove.CompressedImage", "sensor_msgs/msg/CompressedImage")
IMAGE_SCHEMAS = RAW_SCHEMAS + COMPRESSED_SCHEMAS

# encoding -> (channels, cv2 conversion to RGB or None if already RGB)
COLOR_ENCODINGS: dict[str, tuple[int, int | None]] = {
    "rgb8": (3, None),
    "bgr8": (3, cv2.COLOR_BGR2RGB),
    "rgba8": (4, cv2.COLOR_RGBA2RGB),
    "bgra8": (4, cv2.COLOR_BGRA2RGB),
    "mono8": (1, cv2.COLOR_GRAY2RGB),
    "8uc1": (1, cv2.COLOR_GRAY2RGB),
    "8uc3": (3, cv2.COLOR_BGR2RGB),
    "8uc4": (4, cv2.COLOR_BGRA2RGB),
}
DEPTH_ENCODINGS = ("16uc1", "32fc1", "mono16", "16sc1", "32fc", "16u")


class CorruptImage(Exception):
    """One message's payload cannot be decoded (the frame is skipped, not the stream)."""


def stamp_ns(msg, schema_name: str) -> int:
    """Sensor time of a decoded message in integer nanoseconds (0 if unset)."""
    if schema_name.startswith("foxglove."):
        return int(msg.timestamp.seconds) * 1_000_000_000 + int(msg.timestamp.nanos)
    stamp = msg.header.stamp
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def frame_id(msg, schema_name: str) -> str:
    """The message's coordinate frame name ('' if unset)."""
    return str(msg.frame_id if schema_name.startswith("foxglove.") else msg.header.frame_id)


def image_kind(msg, schema_name: str) -> str:
    """'color' for a camera image we decode, 'depth' for depth, else 'unsupported <encoding>'."""
    if schema_name in COMPRESSED_SCHEMAS:
        return "depth" if "compresseddepth" in msg.format.lower().replace(" ", "") else "color"
    enc = msg.encoding.strip().lower()
    if enc in COLOR_ENCODINGS:
        return "color"
    if enc in DEPTH_ENCODINGS:
        return "depth"
    return f"unsupported {msg.encoding}"


def decode_image(msg, schema_name: str) -> np.ndarray:
    """Decoded image message -> (H, W, 3) float32 RGB in [0, 1]. Raises CorruptImage."""
    if schema_name in COMPRESSED_SCHEMAS:
        return decode_compressed(bytes(msg.data), msg.format)
    return decode_raw(bytes(msg.data), int(msg.width), int(msg.height), msg.encoding, int(msg.step))


def decode_raw(data: bytes, width: int, height: int, encoding: str, step: int) -> np.ndarray:
    """Raw 8-bit pixels (rows of `step` bytes, maybe padded) -> (H, W, 3) float32 RGB in [0, 1]."""
    enc = encoding.strip().lower()
    if enc not in COLOR_ENCODINGS:
        raise CorruptImage(f"unsupported encoding '{encoding}' (supported: {', '.join(COLOR_ENCODINGS)})")
    channels, conversion = COLOR_ENCODINGS[enc]
    row = width * channels
    step = step or row  # some writers leave step 0 for unpadded rows
    if width <= 0 or height <= 0 or step < row or len(data) < step * (height - 1) + row:
        raise CorruptImage(f"{len(data)} bytes do not hold a {width}x{height} {encoding} image with step {step}")
    buf = np.frombuffer(data, dtype=np.uint8)
    # Padding: view rows of `step` bytes and keep the first `row` bytes of each.
    rows = np.lib.stride_tricks.as_strided(buf, shape=(height, row), strides=(step, 1))
    img = np.ascontiguousarray(rows).reshape(height, width, channels)
    if conversion is not None:
        img = cv2.cvtColor(img, conversion)
    return img.astype(np.float32) / 255.0


def decode_compressed(data: bytes, fmt: str) -> np.ndarray:
    """Compressed image bytes -> (H, W, 3) float32 RGB in [0, 1].

    image_transport formats such as 'rgb8; jpeg compressed bgr8' name the order of the
    channels inside the file after 'compressed': cv2 returns them as stored, so a file
    that holds rgb8 must not be swapped again.
    """
    img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR) if data else None
    if img is None:
        raise CorruptImage(f"cannot decode {len(data)} bytes of '{fmt}' image data")
    stored = fmt.lower().split("compressed", 1)[1].strip() if "compressed" in fmt.lower() else "bgr8"
    if not stored.startswith("rgb"):
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img.astype(np.float32) / 255.0
