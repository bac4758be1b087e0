"""RenderPicker: every N-th frame, at most M spread evenly over a stream of unknown length."""
import pytest

from nicer_stream.runtime.render_picker import RenderPicker


def run(picker: RenderPicker, n: int) -> list[int]:
    """Offer frames 0..n-1; the kept indices, checking that released ones were kept before."""
    held = set()
    for i in range(n):
        keep, released = picker.offer(i)
        assert set(released) <= held, "released a frame that was not held"
        held -= set(released)
        if keep:
            held.add(i)
    assert sorted(held) == picker.kept
    return picker.kept


def test_short_runs_keep_every_nth_frame():
    assert run(RenderPicker(10, 20), 40) == [0, 10, 20, 30]
    assert run(RenderPicker(10, 20), 200) == list(range(0, 200, 10))  # exactly the cap


@pytest.mark.parametrize("n", [201, 300, 2000, 12345])
def test_long_runs_stay_within_the_cap_evenly_spread(n):
    kept = run(RenderPicker(10, 20), n)
    assert 10 <= len(kept) <= 20
    assert kept[0] == 0
    steps = {b - a for a, b in zip(kept, kept[1:])}
    assert len(steps) == 1 and steps.pop() % 10 == 0  # one stride, a multiple of `every`
    assert n - kept[-1] <= 2 * (kept[1] - kept[0])  # the whole stream is covered


def test_no_cap_is_every_nth():
    assert run(RenderPicker(10, 0), 300) == list(range(0, 300, 10))


def test_each_doubling_lets_go_of_every_other_kept_frame():
    p = RenderPicker(1, 2)
    assert p.offer(0) == (True, [])
    assert p.offer(1) == (True, [])
    assert p.offer(2) == (True, [1])  # three held -> stride 2: frame 1 goes, 2 stays
    assert p.offer(3) == (False, [])
    assert p.offer(4) == (True, [2])  # {0, 2, 4} -> stride 4
    assert p.kept == [0, 4]


def test_the_offered_frame_itself_can_fall_to_its_own_doubling():
    p = RenderPicker(1, 3)
    for i in range(3):
        assert p.offer(i) == (True, [])
    assert p.offer(3) == (False, [1])  # {0, 1, 2, 3} -> stride 2: 1 goes, and 3 is never held
    assert p.kept == [0, 2]


def test_bad_settings_are_errors():
    with pytest.raises(ValueError):
        RenderPicker(0, 20)
    with pytest.raises(ValueError):
        RenderPicker(10, -1)
