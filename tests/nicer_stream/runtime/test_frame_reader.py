"""The read-ahead source reader: every item in order, at most `depth` ahead, source errors at
their item, and a stop that ends the reader."""
import threading
import time

import pytest

from nicer_stream.runtime.frame_reader import ReadAhead


def test_every_item_in_order_and_never_more_than_depth_ahead():
    produced = []

    def source():
        for i in range(20):
            produced.append(i)
            yield i

    with ReadAhead(source(), depth=3) as r:
        it = iter(r)
        assert next(it) == 0
        time.sleep(0.3)  # the reader fills the queue, then waits
        assert len(produced) <= 1 + 3 + 1  # consumed, queued, one in the reader's hand
        assert [0] + list(it) == list(range(20))


def test_a_source_error_is_raised_at_its_item():
    def source():
        yield 1
        raise ValueError("corrupt frame 2")

    with ReadAhead(source()) as r:
        got = []
        with pytest.raises(ValueError, match="corrupt frame 2"):
            for x in r:
                got.append(x)
    assert got == [1]


def test_close_stops_a_reader_that_waits_for_room():
    def endless():
        i = 0
        while True:
            yield i
            i += 1

    r = ReadAhead(endless(), depth=2)
    next(iter(r))
    r.close()
    assert not any(t.name == "reader" and t.is_alive() for t in threading.enumerate())
