"""The mapped frames' brightness store: the reference holds the gauge, new frames start from
the nearest known one, Adam moves only the frames that took a gradient."""
import torch

from nicer_stream.mapping.exposure import FrameExposures


def test_reference_is_a_constant_zero_and_others_take_gradients():
    ex = FrameExposures(lr=0.1)
    rows = ex.rows([5, 7, 9])
    assert ex.reference == 5 and torch.equal(rows, torch.zeros(3, 2))
    loss = ((rows - torch.tensor([0.3, -0.1])) ** 2).sum()  # pulls every frame toward (0.3, -0.1)
    loss.backward()
    ex.step()
    assert ex.value(5) == (0.0, 0.0)
    for i in (7, 9):
        a, b = ex.value(i)
        assert a > 0.05 and b < -0.05


def test_new_frames_start_from_the_nearest_known_frame_and_untouched_frames_stay():
    ex = FrameExposures(lr=0.05)
    ex.rows([0])
    for _ in range(50):
        rows = ex.rows([10, 20])
        ((rows - torch.tensor([[0.2, 0.0], [0.5, 0.1]])) ** 2).sum().backward()
        ex.step()
    a10, a20 = ex.value(10), ex.value(20)
    assert ex.rows([18])[0].tolist() == list(a20)  # nearest: 20
    assert ex.rows([3])[0].tolist() == [0.0, 0.0]  # nearest: the reference
    rows = ex.rows([18])
    (rows ** 2).sum().backward()
    ex.step()
    assert ex.value(10) == a10 and ex.value(20) == a20  # no gradient: Adam leaves them
    assert ex.value(18) != a20
