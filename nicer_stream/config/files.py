"""A preset overridden by nested values or by a .toml / .json file."""
from __future__ import annotations

import json
import tomllib
from dataclasses import fields, is_dataclass, replace
from pathlib import Path
from typing import Any

from nicer_stream.config.presets import preset
from nicer_stream.config.slam import SlamConfig
from nicer_stream.errors import UserError


def override(cfg: Any, values: dict[str, Any], where: str = "config", strict: bool = True) -> Any:
    """Return `cfg` with nested `values` applied; unknown keys raise UserError (`strict=False`
    skips them: a config saved by another version, whose renamed settings cannot matter)."""
    names = {f.name: f for f in fields(cfg)}
    changes = {}
    for key, val in values.items():
        if key not in names:
            if not strict:
                continue
            raise UserError(f"unknown key '{where}.{key}': valid keys are {', '.join(sorted(names))}")
        cur = getattr(cfg, key)
        if is_dataclass(cur):
            if not isinstance(val, dict):
                raise UserError(f"'{where}.{key}' must be a table of settings")
            changes[key] = override(cur, val, f"{where}.{key}", strict)
        else:
            changes[key] = tuple(val) if isinstance(val, list) else val
    return replace(cfg, **changes)


def load(preset_name: str, file: str | Path | None = None) -> SlamConfig:
    """Preset `preset_name`, optionally overridden by a .json or .toml file."""
    cfg = preset(preset_name)
    if file is None:
        return cfg
    path = Path(file)
    if not path.exists():
        raise UserError(f"config file {path} does not exist")
    text = path.read_text()
    kind = "TOML" if path.suffix == ".toml" else "JSON"
    try:  # TOMLDecodeError and JSONDecodeError are ValueErrors
        values = tomllib.loads(text) if kind == "TOML" else json.loads(text)
    except ValueError as e:
        msg = str(e).replace("\n", " ")
        raise UserError(f"config file {path} is not valid {kind} ({msg}): fix it or remove --config") from None
    if not isinstance(values, dict):
        raise UserError(f"config file {path} must hold a table of settings at the top level")
    try:
        return override(cfg, values)
    except UserError as e:
        raise UserError(f"config file {path}: {e}") from None
