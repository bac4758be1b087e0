"""Read a camera calibration file (for video sources).

Formats (chosen by extension):
- `.txt`: one line `fx fy cx cy` (sources.intrinsics_files.read_intrinsics_txt), no distortion.
- `.yaml` / `.yml` / `.xml`: OpenCV FileStorage (K as an `opencv-matrix`) or a ROS
  `camera_info` YAML (`camera_matrix: {rows, cols, data}`, `distortion_coefficients`,
  `distortion_model`, `image_width`, `image_height`).
- `.json`: an object with K (3x3 nested or 9 values, or `{data: [...]}`) and optional D.
Accepted key names are in K_KEYS / D_KEYS / WIDTH_KEYS / HEIGHT_KEYS (case-insensitive).
"""
from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from sources.intrinsics_files import MISSING_HINT, read_intrinsics_txt
from sources.mcap_calibration import CameraCalibration, calibration_from_values

K_KEYS = ("k", "camera_matrix", "cameramatrix", "intrinsic_matrix", "intrinsics", "mtx")
D_KEYS = ("d", "distortion_coefficients", "dist_coeffs", "distcoeffs", "dist", "distortion")
WIDTH_KEYS = ("image_width", "width", "w")
HEIGHT_KEYS = ("image_height", "height", "h")
MODEL_KEYS = ("distortion_model", "model")


def read_calibration_file(path: str | Path) -> CameraCalibration:
    """Parse a calibration file -> CameraCalibration. Raises SourceError with a fix-it hint."""
    path = Path(path)
    if not path.is_file():
        raise SourceError(f"calibration file {path} not found: give an existing file or {MISSING_HINT}")
    suffix = path.suffix.lower()
    if suffix == ".txt":
        return CameraCalibration(read_intrinsics_txt(path), np.zeros(0))
    if suffix == ".json":
        try:
            data = json.loads(path.read_text())
        except (ValueError, UnicodeDecodeError) as e:
            raise SourceError(f"{path} is not valid JSON ({e}): fix it or {MISSING_HINT}") from None
    elif suffix in (".yaml", ".yml", ".xml"):
        data = _read_filestorage(path)
    else:
        raise SourceError(f"calibration file {path}: use .txt (fx fy cx cy), .yaml/.yml/.xml or .json, or {MISSING_HINT}")
    return calibration_from_mapping(data, str(path))


def calibration_from_mapping(data, origin: str) -> CameraCalibration:
    """A parsed YAML/JSON object -> CameraCalibration (see module docstring for keys)."""
    if not isinstance(data, dict):
        raise SourceError(f"{origin}: expected a mapping with K (camera matrix): fix it or {MISSING_HINT}")
    lower = {str(k).lower(): v for k, v in data.items()}
    k = _flat(_first(lower, K_KEYS))
    if k is None or k.size != 9:
        raise SourceError(f"{origin}: no 3x3 camera matrix (keys {', '.join(K_KEYS)}): fix it or {MISSING_HINT}")
    d = _flat(_first(lower, D_KEYS))
    width, height = _first(lower, WIDTH_KEYS), _first(lower, HEIGHT_KEYS)
    model = _first(lower, MODEL_KEYS)
    calib = calibration_from_values(
        k, d, str(model or "plumb_bob"), int(width or 0), int(height or 0), origin=origin
    )
    if calib is None:
        raise SourceError(f"{origin}: camera matrix has no positive focal lengths: fix it or {MISSING_HINT}")
    return calib


def _first(mapping: dict, keys: tuple[str, ...]):
    return next((mapping[key] for key in keys if key in mapping), None)


def _flat(value) -> np.ndarray | None:
    """Matrix-like (ndarray, nested list, ROS `{rows, cols, data}`) -> flat float64 array."""
    if value is None:
        return None
    if isinstance(value, dict):
        value = value.get("data")
    try:
        return np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return None


def _read_filestorage(path: Path):
    """Read YAML/XML with cv2.FileStorage (no PyYAML dependency) -> python objects."""
    try:
        fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except Exception:  # cv2.error, or SystemError on a YAML syntax error
        fs = None
    if fs is None or not fs.isOpened():
        raise SourceError(f"cannot parse {path} as OpenCV/ROS YAML or XML: fix it or {MISSING_HINT}")
    try:
        return _node_value(fs.root())
    finally:
        fs.release()


def _node_value(node):
    """cv2.FileNode -> dict / list / float / str / ndarray (for `opencv-matrix`)."""
    if node.isMap():
        keys = node.keys()
        if "dt" in keys and "data" in keys:
            return node.mat()
        return {k: _node_value(node.getNode(k)) for k in keys}
    if node.isSeq():
        return [_node_value(node.at(i)) for i in range(node.size())]
    if node.isString():
        return node.string()
    if node.isInt() or node.isReal():
        return node.real()
    return None
