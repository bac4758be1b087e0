"""--realtime pacing: frames whose recorded time has passed are dropped and counted."""
import time

from nicer_stream.runtime.pacer import Pacer


def test_pacer_disabled_never_drops():
    p = Pacer(False)
    assert not any(p.drop(t * 0.001) for t in range(100))
    assert p.dropped == 0


def test_pacer_drops_frames_it_cannot_keep_up_with():
    p = Pacer(True)
    assert not p.drop(0.0)  # the first frame starts the clock
    time.sleep(0.05)  # "processing" took 50 ms
    assert p.drop(0.01) and p.drop(0.02)  # already due: dropped
    t0 = time.perf_counter()
    assert not p.drop(0.2)  # in the future: waits for it, then keeps it
    assert time.perf_counter() - t0 > 0.1
    assert p.dropped == 2
