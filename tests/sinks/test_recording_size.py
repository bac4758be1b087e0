"""What keeps a live recording small on a long log: the beta voxels (a few MB each time) are
logged every few map updates, from the first on, not at every update; the keyframes, losses
and renders still at each."""
import numpy as np
import torch

from nicer_stream.runtime.live_outputs import LiveMapOutputs
from nicer_stream.slam.events import MapUpdated


class Calls:
    """A sink stand-in that records which calls came at which map update."""

    def __init__(self):
        self.calls = []

    def log_keyframes(self, poses):
        self.calls.append("keyframes")

    def log_scalars(self, index, values):
        self.calls.append(("scalars", index))


class FakeSlam:
    model, keyframes = "live", [0]

    def __init__(self):
        self.poses = {i: torch.eye(4) for i in range(20)}

    def map_view(self):
        return "model", "beta"


def test_beta_voxels_every_few_updates_the_rest_at_each():
    sink = Calls()
    live = LiveMapOutputs(sink, FakeSlam(), mesh_every=0, beta_every=5)
    voxels = []
    live._log_voxels = lambda model, beta: voxels.append(live.updates)  # logged inline: the update in hand
    for i in range(1, 13):
        live(MapUpdated(i, (i,), 0.5, 10, 1.0), intr=None, render=False)
    assert voxels == [1, 6, 11]
    assert sink.calls.count("keyframes") == 12 and [c[1] for c in sink.calls if c != "keyframes"] == list(range(1, 13))
    none = LiveMapOutputs(sink, FakeSlam(), mesh_every=0, beta_every=0)
    none._log_voxels = lambda model, beta: voxels.append("none")
    none(MapUpdated(1, (1,), 0.5, 10, 1.0), intr=None, render=False)
    assert "none" not in voxels
