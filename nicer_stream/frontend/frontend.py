"""The classical frontend: feature tracks through every frame (matched near where the landmarks
should appear), landmarks triangulated with the poses the SLAM trusts (again as the baseline
widens), a PnP pose per frame that seeds the photometric tracker, and a sliding-window bundle
adjustment over the recent trusted frames. Poses are T_world_cam float64 (4, 4) in the SLAM's world
frame and scale (the landmarks come from its poses, so PnP answers in the same scale)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from nicer_stream.config import FrontendConfig
from nicer_stream.frontend.klt import KltTracks
from nicer_stream.frontend.landmark_archive import Anchor, ArchivedLandmark, LandmarkArchive, scaled_pose
from nicer_stream.grey import to_grey_u8
from nicer_stream.frontend.sift import SiftTracks
from nicer_stream.frontend.schur_ba import bundle_adjust_schur
from nicer_stream.frontend.triangulate import triangulate
from nicer_stream.geometry.camera import project_world as project, unproject_world
from nicer_stream.geometry.pose_estimation import essential_pose, pnp_pose
from nicer_stream.types import Intrinsics


@dataclass(frozen=True)
class FrontendPose:
    """T_world_cam (4, 4) float64 from PnP; RANSAC inliers; landmarks visible in the frame and
    their median z-depth in it (the scene's scale, in the map's unit)."""

    T_world_cam: np.ndarray
    inliers: int
    visible: int
    median_depth: float


@dataclass(frozen=True)
class TwoViewTracks:
    """The frontend's start without depth priors: T_world_cam (4, 4) float64 of the second view
    (the first at the identity), its triangulated inliers (M, 3) world, the essential matrix's
    inlier count and their median parallax in degrees."""

    T_world_second: np.ndarray
    points: np.ndarray
    inliers: int
    parallax_deg: float


def hold_scale(before: list[np.ndarray], after: list[np.ndarray], points: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """The bundle adjustment's result with its scale gauge fixed: poses (T_world_cam (4, 4)) and
    world points (P, 3) scaled about the first camera's centre (held by the adjustment) so the
    first two cameras are as far apart as `before`. Reprojections do not change: scaling the whole
    scene about a point is invisible to every camera."""
    c0 = after[0][:3, 3]
    d_after = float(np.linalg.norm(after[1][:3, 3] - c0))
    if d_after <= 0:
        return after, points
    s = float(np.linalg.norm(before[1][:3, 3] - before[0][:3, 3])) / d_after
    return [scaled_pose(T, c0, s) for T in after], c0 + s * (points - c0)


class ClassicalFrontend:
    """Call `observe` on every frame in input order, `estimate` for a frame's pose, and
    `set_pose` once the SLAM has decided a frame's pose (`trusted=False`: not triangulated from).

    Its landmarks are triangulated with its own poses (PnP, then the local BA) wherever it has
    one: the SLAM's pose is adopted only for frames it could not place (the start). So a map
    that pulls the photometric poses does not corrupt the frontend that is meant to catch it."""

    def __init__(self, cfg: FrontendConfig) -> None:
        self.cfg = cfg
        self.intr: Intrinsics | None = None
        if cfg.features == "sift":
            self.tracks: SiftTracks | KltTracks = SiftTracks(cfg.corners)
        else:
            self.tracks = KltTracks(cfg.corners, cfg.min_distance_px, cfg.fb_px)
        self.obs: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # frame -> (track ids, pixels)
        self.poses: dict[int, np.ndarray] = {}  # trusted poses of observed frames
        self.landmarks: dict[int, np.ndarray] = {}  # track id -> world point (3,)
        self.parallax: dict[int, float] = {}  # track id -> ray angle (deg) its landmark was triangulated with
        self.posed: list[int] = []  # the bundle adjustment's frames, in the order they were posed
        self.own: dict[int, np.ndarray] = {}  # its own PnP poses, by frame
        self.last_ba_rms = float("nan")
        # Landmarks no frame of the window sees, to be recognised when the camera looks back
        # (`landmark_archive.py`); the latest descriptor of every track the window sees; the latest
        # trusted observation of a landmark by a frame that left the window (a fixed camera in the BA).
        self.archive = LandmarkArchive(cfg.archive_landmarks)
        self.descriptor: dict[int, np.ndarray] = {}
        self.anchors: dict[int, Anchor] = {}
        self.recognised = 0  # landmarks recognised again, in all
        # Frames whose observations outlive the window: the first view of a start still waiting
        # for its second (a slow camera needs more frames than the window holds).
        self.pinned: set[int] = set()

    def status_line(self) -> str:
        """Its state in one line, for logs: landmarks, frames in the window, the last BA's RMS."""
        return (f"{len(self.landmarks)} landmarks, {len(self.obs)} observed frames, "
                f"{len(self.posed)} BA frames, BA rms {self.last_ba_rms:.2f} px")

    # -- every frame ---------------------------------------------------------------
    def observe(self, index: int, rgb: np.ndarray, intr: Intrinsics) -> None:
        """Follow the features into this frame (`cfg.features`: SIFT matches or KLT tracks). `rgb`:
        (H, W, 3) float RGB in [0, 1] or (H, W) uint8 grey (`Frame.detail`); `intr` its intrinsics
        (every frame at the same size)."""
        self.intr = intr
        self.obs[index] = self.tracks.step(to_grey_u8(rgb), self._predicted(index), self.cfg.guided_px,
                                             2 * self.cfg.min_inliers)
        if self._recognises():
            self.descriptor.update(zip(self.obs[index][0].tolist(), self.tracks.last_desc))
        unpinned = [k for k in sorted(self.obs) if k not in self.pinned]
        for k in unpinned[: max(0, len(unpinned) - self.cfg.window)]:
            ids_k, uv_k = self.obs.pop(k)
            if k in self.poses and self._recognises():
                T = self.poses[k]
                self.anchors.update((t, Anchor(T, p)) for t, p in zip(ids_k.tolist(), uv_k) if t in self.landmarks)
            self.poses.pop(k, None)
            self.own.pop(k, None)
        self.posed = [k for k in self.posed if k in self.poses]
        # Landmarks of tracks no frame in the window sees any more leave it (to the archive, when it
        # recognises them again): bounded memory.
        seen = set(np.concatenate([o[0] for o in self.obs.values()]).tolist())
        for t in [t for t in self.landmarks if t not in seen]:
            if t in self.descriptor:
                self.archive.add(t, ArchivedLandmark(self.landmarks[t], self.descriptor[t],
                                                     self.parallax.get(t, 0.0), self.anchors.get(t), index))
        self.archive.forget_before(index - self.cfg.reidentify_frames)
        self.landmarks = {k: X for k, X in self.landmarks.items() if k in seen}
        self.parallax = {k: a for k, a in self.parallax.items() if k in seen}
        self.descriptor = {k: d for k, d in self.descriptor.items() if k in seen}
        self.anchors = {k: a for k, a in self.anchors.items() if k in seen}

    def _recognises(self) -> bool:
        """Whether archived landmarks are recognised again (SIFT descriptors, `reidentify_px`)."""
        return self.cfg.reidentify_px > 0 and isinstance(self.tracks, SiftTracks)

    def _predicted(self, index: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Where the landmarks should appear in frame `index`: (track ids (P,), pixels (P, 2)) from
        a constant-velocity pose over the last two frames it placed; None without those."""
        placed = self.placed()
        if self.intr is None or not self.landmarks or index - 1 not in placed or index - 2 not in placed:
            return None
        T1 = placed[index - 1]
        T = T1 @ np.linalg.inv(placed[index - 2]) @ T1
        ids = np.fromiter(self.landmarks, np.int64, len(self.landmarks))
        uv, z = project(T, np.stack(list(self.landmarks.values())), self.intr)
        return ids[z > 0], uv[z > 0]

    def placed(self) -> dict[int, np.ndarray]:
        """Its own pose of every frame in the window it placed (PnP, then its bundle adjustment;
        the SLAM's where it could not place one): consistent with each other."""
        return {**self.own, **self.poses}

    def estimate(self, index: int, T_guess: np.ndarray) -> FrontendPose | None:
        """PnP pose of observed frame `index` from its tracks' landmarks; None when fewer than
        `min_inliers` landmarks agree."""
        if index not in self.obs:
            return None
        res = self._pnp(index, T_guess)
        if self._recognises() and len(self.archive) and index == max(self.obs):
            res = self._recognise(index, res[0] if res is not None else T_guess) or res
        if res is None:
            return None
        X = self.landmark_observations(index)[1]
        z = project(res[0], X, self.intr)[1]
        self.own[index] = res[0]
        return FrontendPose(res[0], res[1], len(X), float(np.median(z)))

    def _pnp(self, index: int, T_guess: np.ndarray, extra: tuple[np.ndarray, np.ndarray] | None = None):
        """PnP (T_world_cam, inliers) of frame `index` from its tracks' landmarks and `extra`
        (pixels (K, 2), world points (K, 3)), started at `T_guess`; None when too few agree."""
        uv, X = self.landmark_observations(index)
        if extra is not None:
            uv, X = np.concatenate([uv, extra[0]]), np.concatenate([X, extra[1]])
        if len(X) < self.cfg.min_inliers:
            return None
        return pnp_pose(X, uv, self.intr, T_guess, self.cfg.reproj_px, self.cfg.min_inliers)

    def _recognise(self, index: int, T: np.ndarray):
        """Archived landmarks recognised among the latest frame `index`'s tracks that have none,
        seen from `T` (its PnP pose, else the caller's guess): matched near their projection
        (`LandmarkArchive.match`), then kept where a PnP over all its landmarks with them
        reprojects them within `reproj_px`. Each kept one takes over its track (the track's pixels
        in every frame become the landmark's observations). Returns that PnP's (T_world_cam,
        inliers), or None when none was kept."""
        ids, uv = self.obs[index]
        free = np.flatnonzero([t not in self.landmarks for t in ids.tolist()])
        rows, tracks = self.archive.match(T, self.intr, uv[free], self.tracks.last_desc[free],
                                          self.cfg.reidentify_px, 0.8)
        if not len(rows):
            return None
        rows = free[rows]
        X = np.stack([self.archive.items[t].point for t in tracks.tolist()])
        res = self._pnp(index, T, (uv[rows], X))
        if res is None:
            return None
        px, z = project(res[0], X, self.intr)
        ok = (z > 0) & (np.linalg.norm(px - uv[rows], axis=1) <= self.cfg.reproj_px)
        if not ok.any():
            return None
        self._take_over(ids[rows][ok], tracks[ok])
        return self._pnp(index, res[0])

    def _take_over(self, old: np.ndarray, tracks: np.ndarray) -> None:
        """Tracks `old` (K,) become the archived landmarks `tracks` (K,), back in the window."""
        at = dict(zip(old.tolist(), tracks.tolist()))
        for k, (ids_k, uv_k) in self.obs.items():
            if np.isin(ids_k, old).any():
                self.obs[k] = (np.array([at.get(t, t) for t in ids_k.tolist()], np.int64), uv_k)
        self.tracks.relabel(old, tracks)
        for o, t in at.items():
            a = self.archive.pop(t)
            self.landmarks[t], self.parallax[t] = a.point, a.parallax_deg
            self.descriptor[t] = self.descriptor.pop(o, a.descriptor)
            if a.anchor is not None:
                self.anchors[t] = a.anchor
        self.recognised += len(at)

    def landmark_observations(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """(pixels (P, 2), world points (P, 3)) of observed frame `index`'s tracks that have a landmark."""
        ids, uv = self.obs[index]
        has = np.array([i in self.landmarks for i in ids.tolist()], bool)
        X = np.stack([self.landmarks[i] for i in ids[has].tolist()]) if has.any() else np.zeros((0, 3))
        return uv[has], X

    def seed_landmarks(self, index: int, depth_at: Callable[[np.ndarray, np.ndarray], np.ndarray],
                       check_scale: bool = False) -> tuple[int, float]:
        """Landmarks from the map's depth for trusted frame `index`'s tracks that have none, when it
        sees fewer than `map_landmarks_below`: `depth_at(T_world_cam (4, 4), uv (N, 2))` gives the
        z-depth (N,) at its pose of all its tracks, nan where the map does not know. Why: a turning
        camera outruns triangulation (no parallax) and loses its landmarks within frames; the map saw
        those places. They count as triangulated with `map_landmark_parallax_deg`, so a wider
        baseline replaces them.

        Where `min_inliers` of its own landmarks have a map depth too (on every call with
        `check_scale`), the median ratio of their depth to the map's is its scale against the map's:
        beyond `map_landmark_scale` of 1 the frontend is rescaled to the map about the frame's centre
        with `map_rescale` (off by default: docs/decisions.md), else nothing is seeded. Returns (landmarks added, that ratio or nan)."""
        ids, uv = self.obs.get(index, (np.zeros(0, np.int64), np.zeros((0, 2))))
        has = np.array([i in self.landmarks for i in ids.tolist()], bool)
        few = has.sum() < self.cfg.map_landmarks_below and not has.all()
        if index not in self.poses or not (few or check_scale):
            return 0, float("nan")
        T = self.poses[index]
        z = depth_at(T, uv)
        ratio = float("nan")
        both = has & np.isfinite(z)
        if both.sum() >= self.cfg.min_inliers:
            X = np.stack([self.landmarks[t] for t in ids[both].tolist()])
            ratio = float(np.median(project(T, X, self.intr)[1] / z[both]))
            if self.off_map_scale(ratio):
                if not self.cfg.map_rescale:
                    return 0, ratio
                self.rescale(T[:3, 3], 1 / ratio)
        if not few:
            return 0, ratio
        ok = ~has & np.isfinite(z) & (z > 0)
        for t, x in zip(ids[ok].tolist(), unproject_world(T, uv[ok], z[ok], self.intr)):
            self.landmarks[t] = x
            self.parallax[t] = self.cfg.map_landmark_parallax_deg
        return int(ok.sum()), ratio

    def off_map_scale(self, ratio: float) -> bool:
        """Whether a ratio of its landmarks' depth to the map's (`seed_landmarks`) is a scale the map
        does not share: beyond `map_landmark_scale` of 1 (nan: not known, so not off)."""
        s = self.cfg.map_landmark_scale
        return bool(np.isfinite(ratio)) and not 1 / s <= ratio <= s

    def rescale(self, centre: np.ndarray, factor: float) -> None:
        """Scale its landmarks and the camera centres of its window by `factor` about the world
        point `centre` (3,): its tracks reproject as before, its unit changes."""
        for poses in (self.poses, self.own):
            for k, T in poses.items():
                poses[k] = scaled_pose(T, centre, factor)
        self.landmarks = {t: centre + factor * (X - centre) for t, X in self.landmarks.items()}
        self.archive.rescale(centre, factor)
        self.anchors = {t: Anchor(scaled_pose(a.T_world_cam, centre, factor), a.uv) for t, a in self.anchors.items()}

    def common_tracks(self, a: int, b: int) -> int:
        """How many tracks observed frames `a` and `b` share (0 when either is not observed)."""
        if a not in self.obs or b not in self.obs:
            return 0
        return len(np.intersect1d(self.obs[a][0], self.obs[b][0]))

    def stale_first_views(self, held: list[int], index: int) -> int:
        """How many of the `held` views (oldest first) a start should pass over: those sharing fewer
        than `2 * min_inliers` tracks with frame `index`, up to the first that shares enough; the
        last held view always stays. Why: a turning camera loses its first view's tracks within a few
        frames, long before the start has parallax (docs/decisions.md)."""
        need = 2 * self.cfg.min_inliers
        drop = 0
        while drop + 1 < len(held) and self.common_tracks(held[drop], index) < need:
            drop += 1
        return drop

    def two_view(self, first: int, second: int, median_m: float, fallback: bool = False) -> TwoViewTracks | None:
        """A start without depth priors: `second`'s pose with `first` at the identity, from the
        essential matrix of their common tracks, scaled so the median depth of the triangulated
        inliers in `first` is `median_m`. None with fewer than 2 * `min_inliers` inliers or median
        parallax below `init_parallax_deg` (half that once fewer than 4 * `min_inliers` tracks are
        common); with `fallback`, below `min_inliers` inliers or `fallback_parallax_deg`."""
        if first not in self.obs or second not in self.obs or (fallback and self.cfg.fallback_parallax_deg <= 0):
            return None
        need = self.cfg.min_inliers * (1 if fallback else 2)
        (ids0, uv0), (ids1, uv1) = self.obs[first], self.obs[second]
        common, i0, i1 = np.intersect1d(ids0, ids1, return_indices=True)
        if len(common) < need:
            return None
        rel = essential_pose(uv0[i0], uv1[i1], self.intr, self.cfg.reproj_px / 2, need)
        if rel is None:
            return None
        T1, n_in, inl = rel
        X, ok = triangulate(np.eye(4), T1, uv0[i0][inl], uv1[i1][inl], self.intr, self.cfg.reproj_px, 0.0)
        if ok.sum() < need:
            return None
        X = X[ok]
        if self.cfg.start_ba:
            T1, X = self._refine_pair(T1, X, uv0[i0][inl][ok], uv1[i1][inl][ok])
        rays0, rays1 = X / np.linalg.norm(X, axis=1, keepdims=True), X - T1[:3, 3]
        rays1 /= np.linalg.norm(rays1, axis=1, keepdims=True)
        parallax = np.degrees(np.median(np.arccos(np.clip((rays0 * rays1).sum(1), -1, 1))))
        # Tracks fading (forward motion past near surfaces) before the parallax grows: half the
        # parallax now beats waiting for a pair with too few common tracks to start from.
        fading = len(common) < 4 * self.cfg.min_inliers
        floor = self.cfg.fallback_parallax_deg if fallback else self.cfg.init_parallax_deg * (0.5 if fading else 1.0)
        if parallax < floor:
            return None
        s = median_m / float(np.median(X[:, 2]))
        T1[:3, 3] *= s
        return TwoViewTracks(T1, X * s, int(n_in), float(parallax))

    def _refine_pair(self, T1: np.ndarray, X: np.ndarray, uv0: np.ndarray, uv1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Two views (the first at the identity, the second at T1 (4, 4)) and their points X (M, 3)
        seen at uv0 / uv1 (M, 2) by a bundle adjustment with the first view held and the baseline's
        length kept (`hold_scale`). Why: RANSAC's essential matrix comes from minimal samples, and
        the start's views are held fixed by every later adjustment (`ba_fixed`), so their error
        stays in the trajectory and in every stereo pair (Replica clip: stereo depth 5% short)."""
        m = len(X)
        cam, pt = np.repeat([0, 1], m), np.tile(np.arange(m), 2)
        before = [np.eye(4), T1]
        poses, X, _ = bundle_adjust_schur(before, 1, X, cam, pt, np.concatenate([uv0, uv1]), self.intr,
                                          self.cfg.reproj_px, self.cfg.ba_iters)
        poses, X = hold_scale(before, poses, X)
        return poses[1], X

    # -- poses the SLAM decided --------------------------------------------------------
    def set_pose(self, index: int, T_world_cam: np.ndarray, trusted: bool = True, adopt: bool = False) -> None:
        """Record the SLAM's pose of `index`; a trusted one triangulates new landmarks against
        the oldest posed frame that saw each track; one that moved far enough runs the local BA.
        Its own PnP pose of the frame is kept over the SLAM's unless `adopt` (the SLAM found its
        own pose unhealthy: `frontend/health.py`)."""
        if adopt:
            self.own.pop(index, None)
        if index not in self.obs or not trusted:
            return
        self.poses[index] = self.own.pop(index, np.asarray(T_world_cam, np.float64))
        self._triangulate(index)
        if self._moved_enough(index):
            self.posed = [k for k in self.posed if k != index] + [index]
            self._bundle_adjust()

    def _moved_enough(self, index: int) -> bool:
        """Whether trusted frame `index` joins the bundle adjustment's frames: the first two do,
        later ones once `ba_baseline_frac` of the median landmark depth from the last to join. A
        window of neighbouring frames of a slow camera (1 cm apart at 2 m, the Replica clip) holds
        the scale by a baseline too short to."""
        if len(self.posed) < 2:
            return True
        ids, _ = self.obs[index]
        X = [self.landmarks[t] for t in ids.tolist() if t in self.landmarks]
        if not X:  # nothing to adjust yet
            return False
        z = project(self.poses[index], np.stack(X), self.intr)[1]
        step = np.linalg.norm(self.poses[index][:3, 3] - self.poses[self.posed[-1]][:3, 3])
        return step >= self.cfg.ba_baseline_frac * float(np.median(z))

    def _triangulate(self, index: int) -> None:
        """Landmarks for this frame's tracks from the oldest posed frame that saw each (the widest
        baseline). A landmark triangulated with little parallax is triangulated again once the
        baseline gives `retriangulate_gain` times its parallax: in forward motion most tracks start
        near `min_parallax_deg`, where half a pixel is ~20% of depth, and such a landmark would
        otherwise bias every later pose."""
        ids, uv = self.obs[index]
        gain, cap = self.cfg.retriangulate_gain, self.cfg.retriangulate_below_deg
        redo = np.array([gain > 0 and self.parallax.get(t, np.inf) < cap for t in ids.tolist()], bool)
        new = ~np.array([i in self.landmarks for i in ids.tolist()], bool) | redo
        for k in sorted(self.poses):  # oldest first: the widest baseline for each track
            if k == index or not new.any():
                continue
            ids_k, uv_k = self.obs[k]
            pos = {t: j for j, t in enumerate(ids_k.tolist())}
            sel = np.array([new[j] and t in pos for j, t in enumerate(ids.tolist())], bool)
            if not sel.any():
                continue
            j_k = np.array([pos[t] for t in ids[sel].tolist()])
            X, ok, angle = triangulate(self.poses[k], self.poses[index], uv_k[j_k], uv[sel], self.intr,
                                       self.cfg.reproj_px, self.cfg.min_parallax_deg, with_angle=True)
            before = np.array([self.parallax.get(t, 0.0) for t in ids[sel].tolist()])
            ok &= angle >= gain * before  # a re-triangulation must widen the baseline
            for t, x, a in zip(ids[sel][ok].tolist(), X[ok], angle[ok]):
                self.landmarks[t] = x
                self.parallax[t] = float(a)
            # A redo is decided by the oldest frame (later ones are narrower); a new track that failed
            # here (e.g. a mismatch in that frame) may still triangulate against a later one.
            new[np.flatnonzero(sel)[ok | redo[sel]]] = False

    def _bundle_adjust(self) -> None:
        """The last `ba_frames` of its frames and their landmarks, the `ba_fixed` posed first held
        (gauge and scale), and, held too, the anchors (`landmark_archive.py`) of those landmarks.
        Order of posing, not of frame index: at the start that holds the two views the SLAM began
        from (frames held between them are posed later)."""
        frames = self.posed[-self.cfg.ba_frames:]
        if self.cfg.ba_frames <= 0 or len(frames) <= self.cfg.ba_fixed or not self.landmarks:
            return
        counts: dict[int, int] = {}
        for k in frames:
            for t in self.obs[k][0].tolist():
                if t in self.landmarks:
                    counts[t] = counts.get(t, 0) + 1
        # seen twice (an anchor counts): constrained
        lm_ids = sorted(t for t, c in counts.items() if c + (t in self.anchors) >= 2)
        if not lm_ids:
            return
        col = {t: j for j, t in enumerate(lm_ids)}
        fixed: dict[int, int] = {}  # anchor pose (by identity) -> its camera among the held ones
        held: list[np.ndarray] = []
        cam, pt, uv = [], [], []
        for t in lm_ids:
            if t in self.anchors:
                a = self.anchors[t]
                if id(a.T_world_cam) not in fixed:
                    fixed[id(a.T_world_cam)] = len(held)
                    held.append(a.T_world_cam)
                cam.append(fixed[id(a.T_world_cam)])
                pt.append(col[t])
                uv.append(a.uv)
        for c, k in enumerate(frames):
            ids_k, uv_k = self.obs[k]
            for j, t in enumerate(ids_k.tolist()):
                if t in col:
                    cam.append(len(held) + c)
                    pt.append(col[t])
                    uv.append(uv_k[j])
        if len(cam) < 6 * len(frames):
            return
        before = [self.poses[k] for k in frames]
        poses, X, self.last_ba_rms = bundle_adjust_schur(
            held + before, len(held) + self.cfg.ba_fixed, np.stack([self.landmarks[t] for t in lm_ids]),
            np.array(cam), np.array(pt), np.array(uv), self.intr, self.cfg.reproj_px, self.cfg.ba_iters)
        poses = poses[len(held):]
        if self.cfg.ba_fixed == 1 and not held:  # held anchors fix the scale themselves
            poses, X = hold_scale(before, poses, X)
        for k, T in zip(frames, poses):
            self.poses[k] = T
        for t, x in zip(lm_ids, X):
            self.landmarks[t] = x
