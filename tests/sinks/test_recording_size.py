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


def test_live_beta_voxels_are_the_sharpest_few(monkeypatch):
    import nicer_stream.runtime.live_outputs as lo
    from types import SimpleNamespace

    monkeypatch.setattr(lo, "LIVE_VOXELS", 100)
    betas = torch.rand(1000, generator=torch.Generator().manual_seed(0)) * 0.1 + 0.01
    centres = torch.rand(1000, 3, generator=torch.Generator().manual_seed(1)) * 2 - 1
    logged = []
    sink = SimpleNamespace(log_beta_voxels=lambda world, beta, size: logged.append((world, beta)))
    slam = SimpleNamespace(cfg=SimpleNamespace(render=SimpleNamespace(beta_voxels=64)))
    model = SimpleNamespace(bound=SimpleNamespace(denormalise=lambda x: 2 * x, half_extent=2.0))
    live = LiveMapOutputs(sink, slam)
    live._log_voxels(model, SimpleNamespace(voxel_betas=lambda: (centres, betas)))
    (world, beta), = logged
    assert len(beta) == 100 and beta.max() <= np.sort(betas.numpy())[99]  # the 100 lowest betas
    order = np.argsort(betas.numpy())[:100]
    assert {tuple(p) for p in np.round(world, 5)} == {tuple(p) for p in np.round(2 * centres.numpy()[order], 5)}
