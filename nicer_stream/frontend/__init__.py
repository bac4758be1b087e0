"""Classical visual odometry under the photometric tracker: SIFT (or KLT) tracks, landmarks
triangulated with the SLAM's poses, PnP per frame and a sparse local bundle adjustment.
It never reads the neural map, so it stays independent of the map's weaknesses."""
