"""The slow reference of `LandmarkArchive.match`: OpenCV's brute-force matcher over every
keypoint-landmark pair, with a (Q, T) mask of the pairs within the radius."""
import cv2
import numpy as np

from nicer_stream.geometry.camera import project_world


def match_reference(archive, T_world_cam, intr, uv, desc, radius_px, ratio):
    empty = np.zeros(0, np.int64), np.zeros(0, np.int64)
    tracks = np.fromiter(archive.items, np.int64, len(archive.items))
    px, z = project_world(T_world_cam, np.stack([a.point for a in archive.items.values()]), intr)
    near = (z > 0) & np.all((px >= -radius_px) & (px < np.array([intr.width, intr.height]) + radius_px), axis=1)
    if near.sum() < 2:
        return empty
    tracks, px = tracks[near], px[near]
    lib = np.stack([archive.items[t].descriptor for t in tracks.tolist()]).astype(np.float32)
    mask = (np.linalg.norm(uv[:, None, :] - px[None], axis=2) <= radius_px).astype(np.uint8)
    pairs = cv2.BFMatcher(cv2.NORM_L2).knnMatch(desc.astype(np.float32), lib, k=2, mask=mask)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    if not good:
        return empty
    bar = np.percentile([m.distance for m in good], 90)
    good += [p[0] for p in pairs if len(p) == 1 and p[0].distance <= bar]
    good.sort(key=lambda m: m.distance)
    rows, used = [], set()
    for m in good:
        if m.trainIdx not in used:
            used.add(m.trainIdx)
            rows.append((m.queryIdx, tracks[m.trainIdx]))
    q, t = np.array(rows, np.int64).T
    return q, t
