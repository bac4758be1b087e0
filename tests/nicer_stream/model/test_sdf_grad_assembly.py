"""The SDF-gradient assembly (`kernels/sdf_grad.cpp`) against its tensor-op reference: values and
every input's gradient, one part and two, with and without the encoding's gradient; gradcheck in
float64 through the kernel; and the kernel against the encoding's explicit Jacobian."""
import pytest
import torch

from nicer_stream.model.positional import ENCODING_KERNEL, positional_encoding  # the same kernel file
from nicer_stream.model.sdf_grad_assembly import SdfGradAssembly, assemble_reference, assemble_sdf_grad

needs_kernel = pytest.mark.skipif(not ENCODING_KERNEL.available(torch.zeros(1)), reason="sdf-gradient kernel could not be built here")
L = 3


def _inputs(n: int, widths: list[int], dtype=torch.float64, seed: int = 0, x_grad: bool = True):
    g = torch.Generator().manual_seed(seed)
    x = (torch.rand(n, 3, dtype=dtype, generator=g) * 2 - 1).requires_grad_(x_grad)
    pe = positional_encoding(x, L)
    parts = [(torch.randn(n, pe.shape[1] + f, dtype=dtype, generator=g).requires_grad_(),
              torch.randn(n, 3, f, dtype=dtype, generator=g).requires_grad_()) for f in widths]
    return x, pe, parts


def _value_and_grads(fn, x, pe, parts, g):
    leaves = ([x] if x.requires_grad else []) + [t for part in parts for t in part]
    out = fn(pe, L, parts)
    grads = torch.autograd.grad(out, leaves, g, retain_graph=True)  # pe's graph serves both paths
    return out.detach(), grads


@needs_kernel
@pytest.mark.parametrize("widths", [[4], [4, 6]])
@pytest.mark.parametrize("x_grad", [True, False])
@pytest.mark.parametrize("dtype,tol", [(torch.float32, 1e-4), (torch.float64, 1e-12)])
def test_kernel_matches_the_reference_values_and_gradients(widths, x_grad, dtype, tol):
    x, pe, parts = _inputs(300, widths, dtype, x_grad=x_grad)
    g = torch.randn(300, 3, dtype=dtype, generator=torch.Generator().manual_seed(5))
    fused = _value_and_grads(lambda p, lv, pa: SdfGradAssembly.apply(p, lv, *[t for q in pa for t in q]), x, pe, parts, g)
    ref = _value_and_grads(assemble_reference, x, pe, parts, g)
    scale = max(1.0, float(ref[0].abs().max()))
    assert torch.allclose(fused[0], ref[0], atol=tol * scale, rtol=tol)
    assert len(fused[1]) == len(ref[1])
    for a, b in zip(fused[1], ref[1]):
        assert torch.allclose(a, b, atol=tol * max(1.0, float(b.abs().max())), rtol=tol)


@needs_kernel
def test_kernel_passes_gradcheck_in_float64():
    x, pe, parts = _inputs(5, [2, 3])
    flat = [t for part in parts for t in part]

    def fn(x, *flat):
        return SdfGradAssembly.apply(positional_encoding(x, L), L, *flat)

    assert torch.autograd.gradcheck(fn, (x, *flat))


@needs_kernel
def test_kernel_equals_the_explicit_jacobian_contraction():
    """grad = Jpe (sum u_pe) + sum_i J_i u_i: the encoding's Jacobian written out, not the reference's formula."""
    x, pe, parts = _inputs(50, [4, 4])
    _, jac_pe = positional_encoding(x.detach(), L, with_tangent=True)  # (N, 3, P)
    p = pe.shape[1]
    want = torch.einsum("nkp,np->nk", jac_pe, sum(u[:, :p] for u, _ in parts))
    for u, jac in parts:
        want = want + torch.einsum("nkf,nf->nk", jac, u[:, p:])
    got = assemble_sdf_grad(pe.detach(), L, [(u.detach(), j.detach()) for u, j in parts])
    assert torch.allclose(got, want, atol=1e-10)


def test_reference_is_taken_where_the_kernel_does_not_apply(monkeypatch):
    monkeypatch.setenv("NICER_STREAM_KERNELS", "0")
    x, pe, parts = _inputs(20, [4], torch.float32)
    out = assemble_sdf_grad(pe, L, parts)
    assert out.grad_fn is not None and "SdfGradAssembly" not in type(out.grad_fn).__name__
    assert torch.equal(out, assemble_reference(pe, L, parts))
