"""Which threads a run uses: mapping inline or on its worker, live renders on the sink worker or not."""
from __future__ import annotations

from dataclasses import dataclass

import torch

from nicer_stream.errors import UserError
from nicer_stream.runtime.mapping_thread import available_cores, split_threads


def mapping_on_worker(mapping_worker: str, sync: bool, device: str) -> bool:
    """Whether mapping runs on its own thread (`--mapping-worker` auto, on or off)."""
    if mapping_worker not in ("auto", "on", "off"):
        raise UserError(f"--mapping-worker must be auto, on or off, got {mapping_worker!r}")
    if sync or mapping_worker == "off":
        return False
    return mapping_worker == "on" or device.startswith("cuda") or available_cores() >= 4


def renders_on_sink_worker(device: str, slam_threads: int) -> bool:
    """Whether the live map renders run on the sink worker (a GPU, or a core the SLAM thread's
    `slam_threads` intra-op threads leave free) or on the SLAM thread: with no spare core, three
    busy threads on two cores made the SLAM thread wait (docs/decisions.md)."""
    return device.startswith("cuda") or available_cores() > slam_threads


@dataclass(frozen=True)
class ThreadPlan:
    """The run's intra-op thread counts and where mapping runs."""

    all_threads: int
    """torch's intra-op threads when the run started (restored at its end)."""
    track_threads: int
    """Intra-op threads of the tracking thread once the mapping worker has the rest."""
    map_threads: int
    """Intra-op threads of the mapping worker."""
    use_worker: bool
    """Mapping calls on the worker thread (else inline with tracking)."""
    description: str
    """How the run is threaded, in words (console and summary.json's `runtime`)."""

    @staticmethod
    def choose(mapping_worker: str, sync: bool, device: str) -> ThreadPlan:
        """The plan for these options on this machine."""
        all_threads = torch.get_num_threads()
        track, mapping = split_threads()
        use_worker = mapping_on_worker(mapping_worker, sync, device)
        text = ("sync (one thread)" if sync else
                f"async (mapping worker; tracking {track} + mapping {mapping} intra-op threads)" if use_worker
                else "async (reader and sink threads; mapping inline with tracking)")
        return ThreadPlan(all_threads, track, mapping, use_worker, text)
