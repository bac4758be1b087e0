"""Gauss-Newton pieces: the ray-to-twist chain rule against autograd through se3_exp, and the
damped solve against least squares."""
import torch

from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.render.renderer import rays_for_pixels
from nicer_stream.tracking.gauss_newton import damped_step, ray_twist_jacobian
from nicer_stream.types import Intrinsics


def _value(o: torch.Tensor, d: torch.Tensor) -> torch.Tensor:
    """A smooth per-ray function of origin and direction (stands in for a rendered colour)."""
    w = torch.tensor([0.3, -1.2, 0.7], dtype=o.dtype)
    return torch.sin(o @ w) + (d * d.roll(1, -1)).sum(-1) + torch.cos(2 * d[:, 2] + o[:, 0])


def test_ray_twist_jacobian_matches_autograd_through_the_pose():
    torch.manual_seed(0)
    intr = Intrinsics(50.0, 52.0, 31.5, 23.5, 64, 48)
    T = se3_exp(torch.tensor([0.4, -0.2, 1.0, 0.3, -0.5, 0.2]).double())
    uv = torch.rand(20, 2).double() * torch.tensor([64.0, 48.0]).double()
    rays = rays_for_pixels(uv.float(), intr, T.float())
    o = rays.origins.double().requires_grad_(True)
    d = rays.dirs.double().requires_grad_(True)
    g_o, g_d = torch.autograd.grad(_value(o, d).sum(), [o, d])
    J = ray_twist_jacobian(g_o, g_d, d.detach(), T[:3, :3])

    def f(xi):
        r = rays_for_pixels(uv.float(), intr, T.float())  # pixel directions only
        Tx = T @ se3_exp(xi)
        d_cam = r.dirs.double() @ T[:3, :3]
        return _value(Tx[:3, 3].expand(len(uv), 3), d_cam @ Tx[:3, :3].T)

    J_ref = torch.autograd.functional.jacobian(f, torch.zeros(6, dtype=torch.float64))
    assert torch.allclose(J, J_ref, atol=1e-5), (J - J_ref).abs().max()


def test_damped_step_without_damping_is_least_squares():
    torch.manual_seed(1)
    J, r = torch.randn(50, 6), torch.randn(50)
    step = damped_step(J, r, torch.ones(50), 0.0)
    ref = torch.linalg.lstsq(J.double(), -r.double()[:, None]).solution[:, 0].float()
    assert torch.allclose(step, ref, atol=1e-5)
    assert damped_step(J, r, torch.ones(50), 1.0).norm() < step.norm()  # damping shortens

