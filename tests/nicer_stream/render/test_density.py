"""laplace_density: Eq. 4 (VolSDF Laplace CDF) with SDF positive in free space."""
import math

import torch

from nicer_stream.render.density import laplace_density


def _closed_form(s: float, beta: float) -> float:
    """sigma = (1/beta) Psi_beta(-s), Psi the zero-mean Laplace CDF of scale beta."""
    y = -s
    cdf = 0.5 * math.exp(y / beta) if y <= 0 else 1 - 0.5 * math.exp(-y / beta)
    return cdf / beta


def test_closed_form_both_branches():
    beta = 0.05
    s = torch.tensor([-0.3, -0.05, -0.001, 0.0, 0.001, 0.02, 0.4], dtype=torch.float64)
    got = laplace_density(s, beta)
    expect = torch.tensor([_closed_form(v, beta) for v in s.tolist()], dtype=torch.float64)
    assert torch.allclose(got, expect, rtol=1e-12, atol=0)
    # Free space (s > 0) is nearly empty, inside (s < 0) approaches 1/beta.
    assert got[-1] < 1e-3 / beta and abs(got[0] - 1 / beta) < 1e-2 / beta


def test_continuous_at_zero_and_tensor_beta():
    beta = torch.tensor([0.01, 0.1], dtype=torch.float64)
    for eps in (0.0, 1e-12, -1e-12):
        got = laplace_density(torch.full((2,), eps, dtype=torch.float64), beta)
        assert torch.allclose(got, 1 / (2 * beta), rtol=1e-9)


def test_monotone_decreasing_in_sdf():
    s = torch.linspace(-1, 1, 2001, dtype=torch.float64)
    d = laplace_density(s, 0.1)
    assert torch.all(d[1:] < d[:-1])


def test_finite_for_huge_sdf_and_gradient():
    s = torch.tensor([-1e6, -1e3, 1e3, 1e6], requires_grad=True)
    d = laplace_density(s, 1e-3)
    assert torch.isfinite(d).all()
    assert torch.allclose(d.detach(), torch.tensor([1e3, 1e3, 0.0, 0.0]))
    d.sum().backward()
    assert torch.isfinite(s.grad).all()


def test_gradient_matches_laplace_pdf():
    # d sigma / d s = -(1/beta) * pdf_beta(s) = -exp(-|s|/beta) / (2 beta^2).
    beta = 0.1
    s = torch.tensor([-0.2, -0.03, 0.05, 0.3], dtype=torch.float64, requires_grad=True)
    laplace_density(s, beta).sum().backward()
    expect = -torch.exp(-s.detach().abs() / beta) / (2 * beta**2)
    assert torch.allclose(s.grad, expect, rtol=1e-10)
