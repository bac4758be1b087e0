"""The lazy grid Adam: torch's Adam where every row is touched, untouched rows left alone,
the compiled pass equal to the tensor-op reference."""
import pytest
import torch

from nicer_stream.mapping.row_adam import RowAdam, kernel_available, row_adam_step, row_adam_step_reference

BETAS, EPS = (0.9, 0.99), 1e-15


def sparse_grad(rows: int, cols: int, frac: float, gen: torch.Generator, dtype=torch.float32) -> torch.Tensor:
    g = torch.randn(rows, cols, generator=gen, dtype=dtype)
    keep = torch.rand(rows, generator=gen) < frac
    g[~keep] = 0
    g[keep.nonzero()[:1, 0], 1:] = 0  # a touched row with a single non-zero entry
    return g


def test_every_row_touched_is_torch_adam():
    gen = torch.Generator().manual_seed(0)
    p0 = torch.randn(50, 4, generator=gen, dtype=torch.float64)
    ref = torch.nn.Parameter(p0.clone())
    opt = torch.optim.Adam([ref], lr=0.03, betas=BETAS, eps=EPS)
    p, m, v = p0.clone(), torch.zeros_like(p0), torch.zeros_like(p0)
    for step in range(1, 8):
        g = torch.randn(50, 4, generator=gen, dtype=torch.float64) + 0.1  # no exact zeros
        ref.grad = g.clone()
        opt.step()
        assert row_adam_step_reference(p, g, m, v, 0.03, BETAS, EPS, step) == 50
        assert not g.any()  # zeroed for the next backward
    torch.testing.assert_close(p, ref.detach(), rtol=1e-12, atol=1e-12)


def test_untouched_rows_keep_parameter_and_moments():
    gen = torch.Generator().manual_seed(1)
    p = torch.randn(200, 4, generator=gen)
    m, v = torch.rand(200, 4, generator=gen), torch.rand(200, 4, generator=gen)
    g = sparse_grad(200, 4, 0.1, gen)
    touched = g.ne(0).any(1)
    before = [t.clone() for t in (p, m, v)]
    n = row_adam_step(p, g, m, v, 0.01, BETAS, EPS, 3)
    assert n == int(touched.sum()) > 0
    for now, was in zip((p, m, v), before):
        assert torch.equal(now[~touched], was[~touched])
        assert not torch.equal(now[touched], was[touched])


@pytest.mark.skipif(not kernel_available(torch.zeros(1)), reason="row Adam kernel could not be built here")
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("update", [True, False])
@pytest.mark.parametrize("width", [2, 4, 32, 3])  # the tables' widths (unrolled in the kernel), any other
def test_compiled_pass_matches_reference(dtype, update, width):
    gen = torch.Generator().manual_seed(2)
    p = torch.randn(5000, width, generator=gen, dtype=dtype)
    m, v = torch.zeros_like(p), torch.zeros_like(p)
    pr, mr, vr = p.clone(), m.clone(), v.clone()
    for step in range(1, 6):
        g = sparse_grad(5000, width, 0.05, gen, dtype)
        gr = g.clone()
        n = row_adam_step(p, g, m, v, 0.04, BETAS, EPS, step, update)
        nr = row_adam_step_reference(pr, gr, mr, vr, 0.04, BETAS, EPS, step, update)
        assert n == nr and not g.any() and not gr.any()
    tol = 1e-5 if dtype == torch.float32 else 1e-12
    for a, b in ((p, pr), (m, mr), (v, vr)):
        torch.testing.assert_close(a, b, rtol=tol, atol=tol)
    if not update:
        assert not m.any()


def test_frozen_tables_are_only_zeroed_and_do_not_count_steps():
    a, b = torch.nn.Parameter(torch.ones(10, 2)), torch.nn.Parameter(torch.ones(10, 2))
    opt = RowAdam({"a": (a, 0.1), "b": (b, 0.1)})
    opt.zero_grad()
    a.grad[3] = 1.0
    b.grad[4] = 1.0
    opt.step(frozen={"b"})
    assert opt.steps == {"a": 1, "b": 0} and opt.touched == {"a": 1, "b": 1}
    assert torch.equal(b.detach(), torch.ones(10, 2)) and not b.grad.any() and not a.grad.any()
    # Adam's first step moves a touched entry by lr (m / sqrt(v) = sign g after bias correction)
    torch.testing.assert_close(a.detach()[3], torch.full((2,), 0.9))
    assert torch.equal(a.detach()[torch.arange(10) != 3], torch.ones(9, 2))
