"""How much of each input frame a recording keeps: a sink spec's query, e.g.
`rerun:run.rrd?images_every=10&image_side=320` (`nicer-stream run` adds its --log-images-every
and --log-image-side to every spec). Poses are logged for every frame regardless."""
from __future__ import annotations

from dataclasses import dataclass

from nicer_stream.errors import UserError


@dataclass(frozen=True)
class SinkOptions:
    """Defaults keep everything as given (what `convert` and `render` want)."""

    images_every: int = 1
    """Log the input image of every N-th frame (frame index % N == 0); the others log the pose only."""
    image_side: int | None = None
    """Downsize logged input images so their longer side is at most this many pixels (None: as given)."""

    def __post_init__(self) -> None:
        if self.images_every < 1:
            raise UserError(f"images_every (--log-images-every) must be at least 1, got {self.images_every}")
        if self.image_side is not None and self.image_side < 1:
            raise UserError(f"image_side (--log-image-side) must be a positive number of pixels (0 or unset: as read), "
                            f"got {self.image_side}")

    def keeps_image(self, index: int) -> bool:
        return int(index) % self.images_every == 0

    def query(self) -> str:
        """The spec query for these options ('' for the defaults)."""
        parts = [f"images_every={self.images_every}"] if self.images_every != 1 else []
        parts += [f"image_side={self.image_side}"] if self.image_side is not None else []
        return "?" + "&".join(parts) if parts else ""


def split_spec(spec: str) -> tuple[str, SinkOptions]:
    """'rerun:a.rrd?images_every=5' -> ('rerun:a.rrd', SinkOptions(images_every=5)). Unknown keys
    and non-integer values are one-line UserErrors."""
    base, _, query = spec.partition("?")
    values: dict[str, int] = {}
    for item in filter(None, query.split("&")):
        key, _, value = item.partition("=")
        if key not in ("images_every", "image_side"):
            raise UserError(f"unknown sink option '{key}' in '{spec}': use images_every=N and image_side=PX")
        try:
            values[key] = int(value)
        except ValueError:
            raise UserError(f"sink option {key} in '{spec}' must be an integer, got '{value}'") from None
    return base, SinkOptions(**values)
