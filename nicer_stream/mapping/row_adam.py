"""Adam on the touched rows of the feature-grid tables (`MappingConfig.grid_adam = "lazy"`).

A mapping iteration's 1024 rays reach ~4% of the fine grid's 4.6M rows, yet torch's (fused)
Adam reads and writes the parameter, gradient and both moments of every row, and the gradient is
zeroed in another full pass. Here only the rows whose gradient is non-zero this step are updated
(their moments and parameter, with the global step's bias correction), and only those gradient
rows are zeroed afterwards: the lazy update Instant-NGP uses for its hash tables (Mueller et al.
2022, Sec. 4: "we skip Adam steps for hash table entries whose gradient is exactly 0"). Rows not
touched keep their moments instead of coasting on them, which is the one difference from Adam.

Tables are (rows, C); their `.grad` must be all zero before the first backward of a call and is
left zero after each `step` (the grid kernel's backward adds into it in place)."""
from __future__ import annotations

import math

import torch

from nicer_stream.model.cpp_kernel import CppKernel

_KERNEL = CppKernel("nicer_stream_row_adam", "row_adam.cpp", ["-O3", "-fopenmp", "-march=native"])


def row_adam_step_reference(p: torch.Tensor, g: torch.Tensor, m: torch.Tensor, v: torch.Tensor, lr: float,
                            betas: tuple[float, float], eps: float, step: int, update: bool = True) -> int:
    """The update in tensor ops (any device): p, g, m, v are (rows, C); `step` >= 1 counts this
    step. Updates p, m, v of the rows where g has a non-zero entry (unless `update` is False),
    zeroes those rows of g and returns how many there were."""
    rows = g.ne(0).any(dim=1).nonzero().squeeze(1)
    if update and len(rows):
        b1, b2 = betas
        gi = g.index_select(0, rows)
        mi = m.index_select(0, rows).mul_(b1).add_(gi, alpha=1 - b1)
        vi = v.index_select(0, rows).mul_(b2).addcmul_(gi, gi, value=1 - b2)
        m.index_copy_(0, rows, mi)
        v.index_copy_(0, rows, vi)
        denom = vi.sqrt().div_(math.sqrt(1 - b2**step)).add_(eps)
        p.index_copy_(0, rows, p.index_select(0, rows).addcdiv_(mi, denom, value=-lr / (1 - b1**step)))
    g.index_fill_(0, rows, 0)
    return int(len(rows))


def row_adam_step(p: torch.Tensor, g: torch.Tensor, m: torch.Tensor, v: torch.Tensor, lr: float,
                  betas: tuple[float, float], eps: float, step: int, update: bool = True) -> int:
    """`row_adam_step_reference` in one compiled pass where available (CPU, float32/64)."""
    if _KERNEL.available(p) and all(t.is_contiguous() and t.dtype == p.dtype for t in (p, g, m, v)):
        b1, b2 = betas
        return int(_KERNEL.module().row_adam_step(p, g, m, v, lr, b1, b2, eps, 1 - b1**step, 1 - b2**step, update))
    return row_adam_step_reference(p, g, m, v, lr, betas, eps, step, update)


def kernel_available(t: torch.Tensor) -> bool:
    """True when `t` can go through the compiled pass."""
    return _KERNEL.available(t)


class RowAdam:
    """Lazy Adam over named (rows, C) tables, each with its own learning rate and step count."""

    def __init__(self, tables: dict[str, tuple[torch.Tensor, float]], betas: tuple[float, float] = (0.9, 0.99),
                 eps: float = 1e-15) -> None:
        self.tables = {name: t for name, (t, _) in tables.items()}
        self.lr = {name: lr for name, (_, lr) in tables.items()}
        self.betas, self.eps = betas, eps
        self.m = {name: torch.zeros_like(t) for name, t in self.tables.items()}
        self.v = {name: torch.zeros_like(t) for name, t in self.tables.items()}
        self.steps = {name: 0 for name in self.tables}
        self.touched: dict[str, int] = {}

    def zero_grad(self) -> None:
        """Every table's gradient set to zeros (allocated if missing)."""
        for t in self.tables.values():
            if t.grad is None:
                t.grad = torch.zeros_like(t)
            else:
                t.grad.zero_()

    @torch.no_grad()
    def step(self, frozen: set[str] = frozenset()) -> None:
        """Update the touched rows of every table not in `frozen`; zero all tables' touched
        gradient rows. `touched` records each table's count of rows."""
        for name, t in self.tables.items():
            update = name not in frozen
            if update:
                self.steps[name] += 1
            self.touched[name] = row_adam_step(t.data, t.grad, self.m[name], self.v[name], self.lr[name], self.betas,
                                               self.eps, max(self.steps[name], 1), update)


if __name__ == "__main__":  # `make setup` builds the kernel once, so the first run does not wait for it
    print("row Adam kernel:", "built" if kernel_available(torch.zeros(1)) else "not available (pure-torch path)")
