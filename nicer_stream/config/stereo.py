"""The keyframes' plane-sweep stereo section."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nicer_stream.config.checks import Checked


@dataclass(frozen=True)
class StereoConfig(Checked):
    """`--priors stereo`: plane-sweep depth of each keyframe from its neighbouring keyframes."""

    window: int = 9
    """ZNCC window side, pixels (odd)."""
    max_side: int | None = 960
    """Sweep the source's larger image (`Frame.detail`) at this longer side, the depth averaged down
    to the map's pixels (None: the map's images); docs/decisions.md."""
    fusion_max_side: int | None = 640
    """`max_side` of the sweep a monocular prior is fitted to (`mono_fusion`); docs/decisions.md."""
    min_planes: int = 48
    """At least this many depth planes."""
    max_planes: int = 160
    """At most this many (cost grows linearly with them)."""
    min_texture: float = 0.005
    """A window whose grey-level std (0..1 units) is below this is untextured: not confident."""
    min_ncc: float = 0.9
    """The best ZNCC must reach this."""
    min_uniqueness: float = 0.0
    """The runner-up plane (2+ planes away) must cost this much more than the best."""
    max_plane_disagreement: int = 2
    """Partners that see a pixel must each put their own best plane within this many planes
    of the joint best."""
    scale: Literal["fixed", "fit"] = "fixed"
    """'fixed': the depth is in the poses' unit, its (w, q) fixed at (1, 0); 'fit': (w, q) refit
    per frame like a monocular prior's (absorbs a keyframe pair's baseline error)."""
    landmark_margin: float = 1.5
    """Depths searched: the frontend's landmarks' 2nd-98th percentiles, near / this and far * this;
    0: the scene bound's whole range (docs/decisions.md)."""
    min_landmarks: int = 30
    """Fewer landmarks than this in front of the keyframe: the scene bound's range."""
    target_baseline: float = 0.15
    """Partners (one earlier, one later frame) at the baseline nearest this fraction of the median
    landmark depth; 0: the nearest keyframes (docs/decisions.md)."""
    partner_frames: int = 10
    """Recent frames kept (images) as stereo partners besides the keyframes."""
    edge_window: int = 5
    """Depth-edge filter: a pixel whose window of known depths (this side) spans more than `edge_rel`
    is dropped; < 2: off (docs/decisions.md)."""
    edge_rel: float = 0.1
    """The span (relative to the nearest depth) the edge filter allows."""
    speckle_size: int = 400
    """Blobs of fewer pixels than this (at the sweep's size) are dropped (`drop_speckles`); 0: off."""
    speckle_step: float = 0.02
    """Neighbours belong to one blob where their inverse depths differ by at most this share
    of the median inverse depth."""
    fill_min_inliers: float = 0.7
    """Large holes are filled by the plane(s) at least this share of their rim lies on within 3%, with
    at most a tenth of it behind (`priors/plane_fill.py`); 0: off."""
    fill_planes: int = 1
    """Planes per hole: up to this many walls, each hole pixel taking the nearest (docs/decisions.md)."""
    normals: bool = False
    """Give keyframes a normal prior computed from the stereo depth; off, because it roughened the
    map (docs/decisions.md)."""
    fill_max_texture: float = 0.015
    """Only holes whose pixels are mostly untextured (grey-level std in a `window` square below this)
    are filled."""
    mono_fusion: bool = False
    """With a monocular provider: fit each keyframe's depth to its own stereo depth (a scale field and a
    shift, `priors/mono_alignment.py`), which fills the stereo's holes (docs/decisions.md)."""
    mono_cells: int = 7
    """Cells of that scale field across the image's longer side (docs/decisions.md)."""
    mono_smooth: float = 1e-4
    """Weight of the squared differences of neighbouring nodes, relative to the data term's
    (docs/decisions.md)."""
    mono_max_rel: float = 0.1
    """Stereo depth further than this share from the fitted monocular depth is replaced by it
    (`fuse_depth`); 0: off (docs/decisions.md)."""
    mono_veto_spread: float = 3.0
    """That share is at least this many robust spreads of the stereo's distance to the fit; 0:
    `mono_max_rel` alone (docs/decisions.md)."""
