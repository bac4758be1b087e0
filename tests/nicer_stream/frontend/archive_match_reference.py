"""The slow reference of `LandmarkArchive.match`: OpenCV's brute-force matcher over every
keypoint-landmark pair, with a (Q, T) mask of the pairs within the radius."""
import cv2
import numpy as np



def match_reference(archive, T_world_cam, intr, uv, desc, radius_px, ratio):
    empty = np.zeros(0, np.int64), np.zeros(0, np.int64)
    tracks, px, lib = archive.in_view(T_world_cam, intr, radius_px)
    if len(tracks) < 2:
        return empty
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
