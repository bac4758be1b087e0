"""`--priors stereo`: each keyframe's depth and normal priors from plane-sweep stereo with its
neighbouring keyframes and the SLAM's own pose estimates (no ground truth, no weights).

The depth is in the poses' unit, so its scale and shift are fixed at (1, 0) (`stereo.scale =
'fixed'`): the map is pulled to the scale of its own trajectory, never to a per-frame fit. A
keyframe's prior is computed when a mapping call first includes it, from one partner before it
and one after where they exist (two on one side where the other has none), and once more when
later partners make a one-sided pair two-sided or a lone partner gets a second. With the
frontend's landmarks, the partners are the frames (keyframes or recent ones) at the baseline
`stereo.target_baseline` asks for and the sweep covers the landmarks' depths; without them, the
nearest keyframes over the scene bound's depths. Each pair's relative pose comes from the
frontend's own poses where it has them (`pair_poses`).

With a monocular provider and `stereo.mono_fusion`, a keyframe's own monocular depth is fitted
to its stereo depth and fills the stereo's holes (`priors/mono_alignment.py`) instead of the
planar fill; its normal prior stays the provider's."""
from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np
import torch

from nicer_stream.config import StereoConfig
from nicer_stream.geometry.camera import in_image, project_world
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mesh.visibility import DepthView
from nicer_stream.model.bound import SceneBound
from nicer_stream.grey import to_grey_f32
from nicer_stream.priors.mono_alignment import align_depth, fuse_depth
from nicer_stream.priors.plane_fill import fill_planar_holes
from nicer_stream.geometry.depth_normals import fill_nearest, normals_from_depth
from nicer_stream.priors.stereo import local_std, shrink_depth, sweep_depth
from nicer_stream.types import DetailImage, Intrinsics


def partners_of(k: int, candidates: list[int], n: int = 2) -> tuple[int, ...]:
    """The `n` candidates nearest to `k` in index, one on each side first (k itself excluded)."""
    before = sorted((c for c in candidates if c < k), reverse=True)
    after = sorted(c for c in candidates if c > k)
    picked = before[:1] + after[:1]
    rest = sorted(before[1:] + after[1:], key=lambda c: abs(c - k))
    return tuple(sorted((picked + rest)[:n]))


def depth_range(T_world_cam: np.ndarray, bound: SceneBound, near_frac: float = 0.02) -> tuple[float, float]:
    """(near, far) z-depths to search: far reaches the bound's farthest corner from the camera."""
    lo, hi = bound.world_min_max()
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    far = float(np.linalg.norm(corners - T_world_cam[:3, 3], axis=1).max())
    return near_frac * far, far


def seen_depths(T_world_cam: np.ndarray, points: np.ndarray | None, intr, min_points: int) -> np.ndarray | None:
    """z-depths (S,) of the world points (P, 3) in front of the camera at T_world_cam and inside
    its image; None with fewer than `min_points` of them."""
    if points is None or len(points) < min_points:
        return None
    uv, z = project_world(T_world_cam, np.asarray(points, np.float64), intr)
    seen = (z > 0) & in_image(uv, intr)
    return z[seen] if seen.sum() >= min_points else None


def landmark_depth_range(T_world_cam: np.ndarray, points: np.ndarray | None, intr, margin: float,
                         min_points: int) -> tuple[float, float] | None:
    """(near, far) z-depths from sparse world points (P, 3) seen in the image at T_world_cam: their
    2nd and 98th depth percentiles, near / margin and far * margin; None with fewer than
    `min_points` of them in front of the camera and inside the image, or margin <= 0."""
    z = seen_depths(T_world_cam, points, intr, min_points) if margin > 0 else None
    if z is None:
        return None
    lo, hi = np.percentile(z, [2, 98])
    return float(lo / margin), float(hi * margin)


def partners_by_baseline(k: int, centres: dict[int, np.ndarray], depth: float, target: float) -> tuple[int, ...]:
    """One candidate before `k` and one after (by index), each the one whose baseline to k (camera
    centres (3,), k's included) over `depth` is nearest `target` in ratio; candidates at k's own
    centre never. Where only one side has candidates (the first frames, the last), a second one
    on that side, nearest half the target: two partners check each other (`sweep_depth` drops
    pixels they disagree on), which one partner cannot (the demo room with GT poses: L1 10.6 ->
    3.4 cm on frame 0, 10.7 -> 4.0 cm on the last)."""
    def nearest(side: list[int], goal: float) -> int | None:
        ratio = {c: float(np.linalg.norm(centres[c] - centres[k])) / depth for c in side}
        ok = [c for c in side if ratio[c] > 0]
        return min(ok, key=lambda c: (abs(np.log(ratio[c] / goal)), abs(c - k))) if ok else None

    sides = [[c for c in centres if c < k], [c for c in centres if c > k]]
    picked = [p for p in (nearest(side, target) for side in sides) if p is not None]
    if len(picked) == 1:
        side = next(s for s in sides if picked[0] in s)
        second = nearest([c for c in side if c != picked[0]], target / 2)
        picked += [second] if second is not None else []
    return tuple(sorted(picked))


def pair_poses(k: int, partners: tuple[int, ...], poses: dict[int, torch.Tensor],
               consistent: dict[int, np.ndarray]) -> dict[int, np.ndarray]:
    """T_world_cam (4, 4) float64 of each partner for the sweep of frame `k`: where `k` and the
    partner both have a `consistent` pose, `poses[k]` times their relative pose from those;
    else `poses[partner]`. Why: a keyframe's pose refined against the map moves it off its
    neighbours' frontend poses by up to ~1.5 degrees (the demo room, measured), and a pair's
    depth depends only on its relative pose (10% of the baseline's parallax per 0.1 degree at
    the demo's ~25 cm baselines)."""
    T_k = poses[k].double().cpu().numpy()
    return {p: T_k @ np.linalg.inv(consistent[k]) @ consistent[p] if k in consistent and p in consistent
            else poses[p].double().cpu().numpy() for p in partners}


def stereo_normals(depth: np.ndarray, intr) -> np.ndarray:
    """(H, W) depth with 0 where unknown -> (H, W, 3) camera normals, zero where unknown: from
    the depth median-filtered (stereo noise) with holes filled only for the differences."""
    smooth = cv2.medianBlur(depth.astype(np.float32), 5)
    valid = (depth > 0) & (smooth > 0)  # isolated pixels vanish in the median: unknown
    if not valid.any():
        return np.zeros(depth.shape + (3,), np.float32)
    n = normals_from_depth(fill_nearest(np.where(valid, smooth, 0.0)), intr)
    # A normal needs its neighbours known too.
    ok = cv2.erode(valid.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return np.where(ok[..., None], n, 0.0).astype(np.float32)


def fusion_params(params: StereoConfig) -> StereoConfig:
    """`params` for the sweep a monocular prior is fitted to: its images at `fusion_max_side`."""
    return dataclasses.replace(params, max_side=params.fusion_max_side)


class StereoPriors:
    """Fills `depth_prior`, `normal_prior` and `depth_scale_shift` of keyframes before mapping."""

    def __init__(self, params: StereoConfig = StereoConfig()) -> None:
        self.params = params
        self.used: dict[int, tuple[int, ...]] = {}  # keyframe -> partners its prior came from
        self.recent: dict[int, np.ndarray] = {}  # the last `partner_frames` images (H, W, 3), by index
        self.sharp: dict[int, tuple[np.ndarray, Intrinsics]] = {}  # larger grey images to sweep (`max_side`)
        # keyframe -> its monocular depth prior and (w, q) before fusion (`stereo.mono_fusion`)
        self.mono: dict[int, tuple[torch.Tensor, tuple[float, float] | None]] = {}
        self.fixed: set[int] = set()  # frames whose depth prior is in the poses' unit: (w, q) = (1, 0)
        # keyframe -> whether its monocular prior was fitted to its stereo (False: the fit failed)
        self.fused: dict[int, bool] = {}
        # keyframe -> its stereo depth (H, W) at the map's size, 0 where unknown: the sweep's with its
        # planar fill, without the monocular fusion (the mesh is culled where it sees through: `measured_views`)
        self.measured: dict[int, np.ndarray] = {}
        self.seconds = 0.0

    def observe(self, index: int, rgb: np.ndarray, detail: DetailImage | None = None) -> None:
        """Keep frame `index`'s image (H, W, 3) as a partner candidate, and its larger grey copy
        (`Frame.detail`) at up to `max_side` pixels where it is larger than `rgb`."""
        self.recent[index] = rgb
        for old in sorted(self.recent)[:-self.params.partner_frames or None]:
            del self.recent[old]
        if detail is not None and self.params.max_side is not None:
            f = min(1.0, self.params.max_side / max(detail.intrinsics.width, detail.intrinsics.height))
            intr = detail.intrinsics.scaled(f)
            if intr.width > rgb.shape[1]:
                g = detail.grey if f == 1.0 else cv2.resize(detail.grey, (intr.width, intr.height),
                                                            interpolation=cv2.INTER_AREA)
                self.sharp[index] = (g, intr)

    def update(self, window: list[int], frames: dict[int, MapFrame], poses: dict[int, torch.Tensor],
               keyframes: list[int], bound: SceneBound, landmarks: np.ndarray | None = None,
               consistent: dict[int, np.ndarray] | None = None) -> list[int]:
        """Compute the priors the window's frames lack (or have one-sided); returns those updated.
        `landmarks` (P, 3) world points (the frontend's) narrow each sweep's depth range.
        `consistent`: T_world_cam (4, 4) of frames from one self-consistent estimator (the
        frontend's); a pair whose frames both have one takes its relative pose from them (`pair_poses`)."""
        t0 = time.perf_counter()
        keep = set(keyframes) | set(self.recent)
        self.sharp = {i: v for i, v in self.sharp.items() if i in keep}
        candidates = [k for k in keyframes if k in frames and k in poses]
        pool = self._images(frames, candidates, poses)
        self.mono = {i: d for i, d in self.mono.items() if i in keep or i in frames}
        done = []
        for k in window:
            if k not in frames or k not in poses:
                continue
            if k not in self.used and frames[k].depth_prior is not None:
                self.mono.setdefault(k, (frames[k].depth_prior, frames[k].depth_scale_shift))
            images = {i: rgb for i, rgb in pool.items() if i != k and rgb.shape == tuple(frames[k].rgb.shape)}
            partners = self._partners(k, images, poses, frames[k].intr, landmarks)
            partners = partners or partners_of(k, [c for c in candidates if c != k])
            if not partners or partners == self.used.get(k):
                continue
            old = self.used.get(k)
            two_sided = min(partners) < k < max(partners)
            if old is not None and (min(old) < k < max(old) or not (two_sided or len(partners) > len(old))):
                continue  # already two-sided, or no better now (better: two-sided, or a second partner)
            pair = pair_poses(k, partners, poses, consistent or {})
            sharp = [self.sharp.get(i) for i in (k, *partners)]
            if all(v is not None and v[1] == sharp[0][1] for v in sharp):  # every image larger, one size
                (ref, intr), rest = sharp[0], sharp[1:]
                self._compute(frames[k], [(g, pair[p]) for (g, _), p in zip(rest, partners)], poses, bound,
                              landmarks, (ref, intr))
            else:
                self._compute(frames[k], [(images[p], pair[p]) for p in partners], poses, bound, landmarks)
            self.used[k] = partners
            done.append(k)
        self.seconds += time.perf_counter() - t0
        return done

    def _images(self, frames: dict[int, MapFrame], keyframes: list[int],
                poses: dict[int, torch.Tensor]) -> dict[int, np.ndarray]:
        """Partner candidates' images (keyframes', some halved, and the recent frames'), by index."""
        out = {c: frames[c].rgb.cpu().numpy() for c in keyframes}
        out.update({i: rgb for i, rgb in self.recent.items() if i in poses})
        return out

    def _partners(self, k: int, images: dict[int, np.ndarray], poses: dict[int, torch.Tensor], intr,
                  landmarks: np.ndarray | None) -> tuple[int, ...]:
        """Partners by baseline (`target_baseline` of the median landmark depth); () where that
        cannot be judged (no landmarks, or switched off)."""
        T = poses[k].double().cpu().numpy()
        z = seen_depths(T, landmarks, intr, self.params.min_landmarks) if self.params.target_baseline > 0 else None
        if z is None:
            return ()
        centres = {i: poses[i].double().cpu().numpy()[:3, 3] for i in list(images) + [k]}
        return partners_by_baseline(k, centres, float(np.median(z)), self.params.target_baseline)

    def _compute(self, f: MapFrame, partners: list[tuple[np.ndarray, np.ndarray]], poses: dict[int, torch.Tensor],
                 bound: SceneBound, landmarks: np.ndarray | None = None,
                 sharp: tuple[np.ndarray, Intrinsics] | None = None) -> None:
        """f's priors from `partners`: (image, T_world_cam (4, 4) float64) pairs, images (H, W, 3) at
        the map's size, or grey at `sharp`'s size when `sharp` gives f's own larger image and its
        intrinsics (the depth is then averaged down to the map's pixels)."""
        T = poses[f.index].double().cpu().numpy()
        near, far = depth_range(T, bound)
        seen = landmark_depth_range(T, landmarks, f.intr, self.params.landmark_margin, self.params.min_landmarks)
        if seen is not None and max(near, seen[0]) < min(far, seen[1]):
            near, far = max(near, seen[0]), min(far, seen[1])
        if sharp is None:
            depth = sweep_depth(f.rgb.cpu().numpy(), T, partners, f.intr, near, far, self.params)
        else:
            depth = sweep_depth(sharp[0], T, partners, sharp[1], near, far, self.params)
            depth = shrink_depth(depth, f.intr.width, f.intr.height)
        mono = self.mono.get(f.index)
        if mono is not None:
            self.measured[f.index] = np.array(depth, np.float32)  # not the monocular fill (~10% distorted)
            self._fuse(f, depth, mono)
            return
        if self.params.fill_min_inliers > 0:
            blank = local_std(to_grey_f32(f.rgb.cpu().numpy()), self.params.window) < self.params.fill_max_texture
            depth = fill_planar_holes(depth, f.intr, blank, min_inliers=self.params.fill_min_inliers,
                                      max_planes=self.params.fill_planes)
        self.measured[f.index] = np.array(depth, np.float32)  # with its planar fill, checked against the sweep
        f.depth_prior = torch.as_tensor(depth, device=f.rgb.device)
        f.normal_prior = torch.as_tensor(stereo_normals(depth, f.intr), device=f.rgb.device) if self.params.normals else None
        f.depth_scale_shift = (1.0, 0.0) if self.params.scale == "fixed" else None
        self._mark(f.index, self.params.scale == "fixed")

    def _fuse(self, f: MapFrame, depth: np.ndarray, mono: tuple[torch.Tensor, tuple[float, float] | None]) -> None:
        """f's monocular depth `mono` ((H, W) prior, its (w, q)) fitted to its stereo `depth`
        (H, W, 0 where unknown) and filling its holes; where the fit fails (too little stereo
        depth) f keeps its monocular prior and (w, q)."""
        prior = mono[0].cpu().numpy()
        if prior.shape != depth.shape:
            prior = cv2.resize(prior, depth.shape[::-1], interpolation=cv2.INTER_LINEAR)
        aligned = align_depth(prior, depth, self.params.mono_cells, self.params.mono_smooth)
        self.fused[f.index] = aligned is not None
        if aligned is None:
            f.depth_prior, f.depth_scale_shift = mono
            self._mark(f.index, False)
            return
        f.depth_prior = torch.as_tensor(fuse_depth(depth, aligned, self.params.mono_max_rel,
                                                   self.params.mono_veto_spread), device=f.rgb.device)
        f.depth_scale_shift = (1.0, 0.0)
        self._mark(f.index, True)

    def measured_views(self, poses: dict[int, np.ndarray], intr: Intrinsics) -> list[DepthView]:
        """Each swept keyframe's measured depth as a `DepthView` at its pose T_world_cam (4, 4) in
        `poses` (keyframes without one are left out); `intr` is the map's."""
        return [DepthView(np.asarray(poses[k], np.float64), intr, d) for k, d in sorted(self.measured.items())
                if k in poses and d.shape == (intr.height, intr.width)]

    def fusion_note(self, what: str = "keyframe") -> str:
        """How many `what`s' monocular priors were fitted to their stereo, for the run's summary."""
        n, ok = len(self.fused), sum(self.fused.values())
        if n == 0:
            return f"no {what} was swept"
        kept = f"; {n - ok} kept the monocular prior alone (too little stereo depth)" if ok < n else ""
        return f"{ok} of {n} {what}s{kept}"

    def _mark(self, index: int, fixed: bool) -> None:
        (self.fixed.add if fixed else self.fixed.discard)(index)
