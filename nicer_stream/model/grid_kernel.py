"""The compiled CPU kernel for multi-level grid interpolation (`kernels/grid_interp.cpp`).

Built on first use (`cpp_kernel.py`). Where it cannot be built, on a GPU, or with
NICER_STREAM_KERNELS=0, the grids use their pure-torch reference paths (same values and
gradients; tests compare both).
"""
from __future__ import annotations

import torch

from nicer_stream.model.cpp_kernel import CppKernel
from nicer_stream.model.gather import gradient_target

# -march=native: this CPU's vector width (AVX2 here) for the corner weights and the channel loops,
# a mapping iteration ~8% faster; -ffp-contract=off: no fused multiply-adds, so the results are
# bit-identical to the plain -O3 build on every CPU (docs/decisions.md).
_KERNEL = CppKernel("nicer_stream_grid_interp", "grid_interp.cpp",
                    ["-O3", "-fopenmp", "-march=native", "-ffp-contract=off"])
_load = _KERNEL.module


def kernel_available(t: torch.Tensor) -> bool:
    """True when `t` (a table or points) can go through the compiled kernel."""
    return _KERNEL.available(t)


class GridSpec:
    """Per-level layout of a grid table: vertex resolution, first row, rows, hashed."""

    def __init__(self, res: list[int], offsets: list[int], sizes: list[int], hashed: list[bool]) -> None:
        self.res = torch.tensor(res, dtype=torch.long)
        self.offsets = torch.tensor(offsets, dtype=torch.long)
        self.sizes = torch.tensor(sizes, dtype=torch.long)
        self.hashed = torch.tensor(hashed, dtype=torch.bool)

    def args(self):
        return self.res, self.offsets, self.sizes, self.hashed


class GridInterp(torch.autograd.Function):
    """apply(table (R, C), x (N, 3), spec, with_jac) -> (out (N, L*C), jac (N, 3, L*C) or empty).

    Like `gather.gather_rows`, a leaf table that already holds a `.grad` buffer gets its
    gradient added in place (`.backward()` semantics)."""

    @staticmethod
    def forward(ctx, table, x, spec: GridSpec, with_jac: bool):
        x = x.contiguous()
        out, jac = _load().grid_forward(table.detach(), x.detach(), *spec.args(), with_jac)
        ctx.save_for_backward(x)
        ctx.table, ctx.spec = table, spec
        if not with_jac:
            ctx.mark_non_differentiable(jac)
        return out, jac

    @staticmethod
    def backward(ctx, g_out, g_jac):
        (x,) = ctx.saved_tensors
        table = ctx.table
        need_table, need_x = ctx.needs_input_grad[0], ctx.needs_input_grad[1]
        empty = table.new_zeros(0)  # the kernel's "absent" for g_jac and the table gradient
        if g_out is None:
            g_out = table.new_zeros(x.shape[0], ctx.spec.res.numel() * table.shape[1])
        g_jac = empty if g_jac is None else g_jac.contiguous()
        grad_table, in_place = gradient_target(table) if need_table else (empty, False)
        g_x = _load().grid_backward(table.detach(), x, *ctx.spec.args(), g_out.contiguous(), g_jac, grad_table, need_x)
        return (grad_table if need_table and not in_place else None), (g_x if need_x else None), None, None


def grid_interp(table: torch.Tensor, x: torch.Tensor, spec: GridSpec, with_jac: bool):
    """Features (N, L*C) and, if `with_jac`, d/dx (N, 3, L*C) (else None) through the kernel."""
    out, jac = GridInterp.apply(table, x, spec, with_jac)
    return out, (jac if with_jac else None)


if __name__ == "__main__":  # `make setup` builds the kernel once, so the first run does not wait for it
    print("grid kernel:", "built" if kernel_available(torch.zeros(1)) else "not available (pure-torch path)")
