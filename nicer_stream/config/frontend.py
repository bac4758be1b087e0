"""The classical frontend's section."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nicer_stream.config.checks import Checked


@dataclass(frozen=True)
class FrontendConfig(Checked):
    """The classical frontend (`tracking.frontend = 'classical'`, `nicer_stream/frontend/`)."""

    max_side: int | None = 1280
    """The frontend works on the source's image up to this longer side (`Frame.detail`), not on the
    map's smaller one (None: the map's); docs/decisions.md."""
    features: Literal["sift", "klt"] = "sift"
    """'sift': SIFT keypoints matched to each track's latest descriptor; 'klt': Shi-Tomasi
    corners followed by pyramidal Lucas-Kanade (drifts on smooth texture: `frontend/sift.py`)."""
    corners: int = 1000
    """Features per frame (SIFT keypoints, or KLT corners kept alive); 400 lost the scale on a
    real camera (docs/decisions.md)."""
    min_distance_px: float = 8.0
    """KLT: minimum spacing of corners, pixels."""
    fb_px: float = 1.0
    """KLT: a track survives a frame when tracking back lands within this many pixels."""
    window: int = 40
    """Frames whose observations are kept (landmarks no frame in it sees are dropped)."""
    min_parallax_deg: float = 1.0
    """Triangulate a track once its two views' rays are this far apart."""
    guided_px: float = 10.0
    """A track with a landmark matches only keypoints this close to where a constant-velocity
    pose puts it (SIFT; 0: anywhere in the image)."""
    retriangulate_gain: float = 2.0
    """A landmark is triangulated again from a baseline giving this many times its parallax
    (0: never; landmarks then move only in the bundle adjustment)."""
    retriangulate_below_deg: float = 5.0
    """... while its parallax is below this many degrees (enough for ~2% depth at half a pixel)."""
    reproj_px: float = 2.0
    """Inlier threshold of PnP, triangulation and the BA's Huber loss, pixels."""
    min_inliers: int = 30
    """A PnP pose needs this many agreeing landmarks."""
    init_parallax_deg: float = 2.0
    """Without a depth prior, the SLAM starts once the first frame and the latest share tracks
    whose median parallax is this large (the essential matrix gives the second pose)."""
    fallback_parallax_deg: float = 0.0
    """... and when no held frame met it, the held frame with the widest median parallax above this
    (0: none, the first frame starts alone). Not a default (docs/decisions.md)."""
    start_ba: bool = True
    """Refine the start's two views by a bundle adjustment (the first view and the baseline's length
    held) before any other frame is posed against them (docs/decisions.md)."""
    prior_start: bool = True
    """With depth priors too, start from the frontend's two views, each prior fitted to their
    triangulated points; False, or where that fails: dense flow (`two_view_init`)."""
    reidentify_px: float = 20.0
    """A landmark that left the window is recognised again (its SIFT descriptor) by a track
    without one within this many pixels of its projection (0: never; `frontend/landmark_archive.py`)."""
    reidentify_frames: int = 150
    """... for this many frames after it left (a revisit after longer is a loop: the drift since is
    the pose graph's to correct, not the local BA's) ..."""
    archive_landmarks: int = 20000
    """... and at most this many landmarks kept for it, the oldest forgotten first."""
    ba_frames: int = 15
    """Frames in the local bundle adjustment (0: none): the latest trusted frames that each moved
    `ba_baseline_frac` from the one before; it runs whenever one joins."""
    ba_baseline_frac: float = 0.02
    """... of the median depth of the landmarks they see (every frame on the street at 1 m a
    frame, every ~4th on the Replica clip)."""
    ba_fixed: int = 3
    """Its oldest this many frames stay fixed (gauge and scale); with 1, the adjusted window is
    rescaled about that frame so its two oldest frames keep their distance (`hold_scale`)."""
    ba_iters: int = 10
    """Its Levenberg-Marquardt iterations at most."""
    map_landmarks_below: int = 90
    """A trusted frame seeing fewer landmarks than this gets landmarks for its other tracks from
    the map's rendered depth (0: never; `ClassicalFrontend.seed_landmarks`)."""
    map_landmark_parallax_deg: float = 2.0
    """Such a landmark counts as triangulated with this parallax (a baseline giving
    `retriangulate_gain` times it triangulates the track again)."""
    map_landmark_opacity: float = 0.9
    """... and comes only from rays the map renders at least this opaque ..."""
    map_landmark_samples: float = 20.0
    """... whose surface lies in a voxel that mapping sampled at least this many times (the
    locally adaptive beta's counter): elsewhere the map is still its initial sphere."""
    map_landmark_scale: float = 1.25
    """The frame's own landmarks, where it has some, more than this factor deeper or shallower than
    the map's depth (median) are a scale the map does not share ..."""
    map_rescale: bool = False
    """... and the frontend is rescaled to the map's (checked at every keyframe); False: such a
    frame seeds nothing and the frontend keeps its scale."""
    max_disagreement_depth_frac: float = 0.005
    """Photometric and frontend poses further apart than this fraction of the landmarks' median depth
    (or `max_disagreement_frac` of the motion, if larger) are a tracking loss."""
    max_disagreement_frac: float = 0.3
    """See `max_disagreement_depth_frac`."""
    max_disagreement_deg: float = 2.0
    """Rotation bound of the same check, degrees."""
    evidence_ratio: float = 0.85
    """When they disagree, the pose whose loss against the map is below this times the other's is
    kept; within it, the one nearer the constant-velocity motion."""
