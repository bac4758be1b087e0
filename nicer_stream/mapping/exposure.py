"""The mapped frames' affine brightness (a, b) (`losses/brightness.py`), held across mapping
calls and optimised with the map.

The first frame registered is the reference: its (a, b) stays (0, 0), which fixes the gauge
(the map's colours could otherwise trade a common gain and bias with every frame). A frame
seen for the first time starts from the registered frame nearest in index: exposure drifts
slowly, so that start is closer than (0, 0) on a long log.
"""
from __future__ import annotations

import torch


class FrameExposures:
    """Per-frame (2,) parameters with their own Adam (its moments carry over between calls)."""

    def __init__(self, lr: float, device: torch.device | str = "cpu") -> None:
        self.lr, self.device = lr, torch.device(device)
        self.reference: int | None = None
        self.params: dict[int, torch.nn.Parameter] = {}
        self.opt: torch.optim.Adam | None = None

    def _register(self, index: int) -> None:
        if self.reference is None:
            self.reference = index
            return
        nearest = min([self.reference, *self.params], key=lambda k: abs(k - index))
        start = torch.zeros(2, device=self.device) if nearest == self.reference else self.params[nearest].detach().clone()
        p = torch.nn.Parameter(start)
        self.params[index] = p
        if self.opt is None:
            self.opt = torch.optim.Adam([p], lr=self.lr)
        else:
            self.opt.add_param_group({"params": [p], "lr": self.lr})

    def rows(self, indices: list[int]) -> torch.Tensor:
        """(F, 2) (a, b) of frames `indices` in that order, differentiable in each frame's
        parameter (the reference's row is a constant zero); new frames are registered."""
        for i in indices:
            if i != self.reference and i not in self.params:
                self._register(i)
        zero = torch.zeros(2, device=self.device)
        return torch.stack([zero if i == self.reference else self.params[i] for i in indices])

    def step(self) -> None:
        """One Adam step on the frames with a gradient, then clear the gradients."""
        if self.opt is None:
            return
        self.opt.step()
        self.opt.zero_grad(set_to_none=True)

    def value(self, index: int) -> tuple[float, float]:
        """(a, b) of frame `index` ((0, 0) for the reference and frames never mapped)."""
        p = self.params.get(index)
        return (0.0, 0.0) if p is None else tuple(p.detach().tolist())
