"""How a config section checks its values when it is built: type, mode (a `Literal`) and range."""
from __future__ import annotations

import math
import types
from dataclasses import fields, is_dataclass
from functools import cache
from typing import Any, ClassVar, Literal, Union, get_args, get_origin, get_type_hints

from nicer_stream.errors import UserError


# Ranges beyond "a number >= 0", which every int and float setting must be.
FRACTIONS = {"fine_start", "ba_start", "final_color_start", "batch_color_start", "keyframe_min_overlap",
             "evidence_ratio", "fill_min_inliers", "min_ncc", "final_lr_end_factor", "map_landmark_opacity"}
POSITIVE = {"max_side", "fusion_max_side", "rays", "chunk_rays", "resolution", "beta_voxels", "lr", "half_extent",
            "coarse_res", "fine_res_min", "fine_res_max", "color_res_min", "color_res_max", "window", "corners"}
SIGNED = {"centre"}


def _accepts(hint: Any, value: Any, name: str) -> str | None:
    """None when `value` fits the annotation `hint` and the range of `name`, else what it must be."""
    if get_origin(hint) in (Union, types.UnionType):
        args = [a for a in get_args(hint) if a is not type(None)]
        if value is None:
            return None if len(args) < len(get_args(hint)) else "must be set"
        hint = args[0]
    if get_origin(hint) is Literal:
        return None if value in get_args(hint) else "must be one of " + ", ".join(repr(a) for a in get_args(hint))
    if get_origin(hint) is tuple:
        ok = isinstance(value, tuple) and len(value) == len(get_args(hint))
        ok = ok and all(_accepts(a, v, name) is None for a, v in zip(get_args(hint), value))
        return None if ok else f"must be {len(get_args(hint))} numbers"
    if hint is bool:
        return None if isinstance(value, bool) else "must be true or false"
    if hint is str:
        return None if isinstance(value, str) else "must be a string"
    if hint in (int, float):
        kind = "an integer" if hint is int else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float) if hint is float else int):
            return f"must be {kind}"
        if name in SIGNED:
            return None if math.isfinite(value) else f"must be {kind}"
        if name in FRACTIONS:
            return None if 0 <= value <= 1 else f"must be {kind} in [0, 1]"
        if name in POSITIVE:
            return None if 0 < value < math.inf else f"must be {kind} > 0"
        return None if 0 <= value < math.inf else f"must be {kind} >= 0"
    return None


@cache
def _hints(cls: type) -> dict[str, Any]:
    return get_type_hints(cls)


def check(section: Any, where: str) -> None:
    """Raise a one-line UserError naming the first field of `section` whose value does not fit."""
    for f in fields(section):
        value = getattr(section, f.name)
        if is_dataclass(value):
            continue
        problem = _accepts(_hints(type(section))[f.name], value, f.name)
        if problem:
            raise UserError(f"{where}{f.name} {problem}, got {value!r}")


class Checked:
    """A config section that checks its values when built (a preset, `replace`, a file). Its
    messages name a key by `where`: the section's field in SlamConfig, which is its class name
    without "Config" in lower case ("mapping." for MappingConfig; "" for SlamConfig itself)."""

    where: ClassVar[str] = ""

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        name = cls.__name__.removesuffix("Config").lower()
        cls.where = "" if name == "slam" else f"{name}."

    def __post_init__(self) -> None:
        check(self, self.where)
