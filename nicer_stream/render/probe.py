"""The probe pass: SDF and density at uniform samples along each ray (no gradient), whose
volume-rendering weights place the importance samples.

A ray's weights behind the point where its transmittance has fallen below exp(-stop_tau)
sum to less than that: they cannot move the importance samples (`sample_pdf` pads every
weight with 1e-5). So the probes are evaluated front to back in segments and a ray stops
once its optical depth passes `stop_tau`; its remaining probes get density 0. In a room,
half of the paper's 640 probes per ray lie behind the first wall.
"""
from __future__ import annotations

import torch

from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.density import laplace_density
from nicer_stream.render.volume import render_weights

# Probe points per forward pass: at the paper's sizes (8096 rays x 640 probes = 5.2M points)
# one pass would allocate ~1.3 GB per hidden layer; chunks of this size stay in cache-sized
# allocations. `fast` (1024 x 32) fits in one chunk.
PROBE_CHUNK = 1 << 17
# Probes per ray evaluated between two checks of the optical depth: at the paper's 640 probes
# the early stop saves ~10% per iteration; at `fast`'s 32 one pass is cheaper (docs/decisions.md).
SEGMENT = 64


def probe_sdf(model: SceneModel, x: torch.Tensor, use_fine: bool, chunk: int = PROBE_CHUNK) -> torch.Tensor:
    """SDF (N,) at normalised points x (N, 3), without gradient, `chunk` points at a time."""
    if x.shape[0] <= chunk:
        return model.geometry.sdf(x, use_fine=use_fine)
    return torch.cat([model.geometry.sdf(x[i:i + chunk], use_fine=use_fine) for i in range(0, x.shape[0], chunk)])


def composite_deltas(t: torch.Tensor, far: torch.Tensor) -> torch.Tensor:
    """(R, S) sorted sample distances -> interval lengths; the last runs to `far` (R,)."""
    last = (far[:, None] - t[:, -1:]).clamp_min(1e-4)
    return torch.cat([t[:, 1:] - t[:, :-1], last], dim=-1)


# The SDF `probe_pass` reports at probes it skipped: behind the point where their ray's light was
# spent, so "inside a solid" (density 1/beta) is what they stand for.
SKIPPED_SDF = -1e3


@torch.no_grad()
def probe_pass(model: SceneModel, beta: BetaField, x: torch.Tensor, deltas: torch.Tensor, use_fine: bool,
               stop_tau: float | None = None, segment: int = SEGMENT) -> tuple[torch.Tensor, torch.Tensor]:
    """Weights (R, P) and SDF (R, P) of the probes x (R, P, 3) (normalised, sorted along each
    ray) with interval lengths `deltas` (R, P).

    `stop_tau` None evaluates every probe (the reference). Otherwise the P probes are taken
    in runs of `segment` front to back, and a ray whose optical depth has passed `stop_tau`
    after a run skips the rest (density 0 there, SDF `SKIPPED_SDF`): each weight then differs
    from the reference's by less than exp(-stop_tau), their sum by less than that too. With
    fewer than two runs' worth of probes (`fast`: 32) the one pass is cheaper."""
    r, p = deltas.shape
    if stop_tau is None or p < 2 * segment:
        sdf = probe_sdf(model, x.reshape(-1, 3), use_fine).reshape(r, p)
        return render_weights(laplace_density(sdf, beta(x)), deltas), sdf
    sigma = deltas.new_zeros(r, p)
    sdf_all = deltas.new_full((r, p), SKIPPED_SDF)
    tau = deltas.new_zeros(r)
    alive = torch.arange(r, device=deltas.device)
    for c0 in range(0, p, segment):
        c1 = min(c0 + segment, p)
        xs = x[alive, c0:c1]
        sdf = probe_sdf(model, xs.reshape(-1, 3), use_fine).reshape(xs.shape[:2])
        sig = laplace_density(sdf, beta(xs))
        sigma[alive, c0:c1] = sig
        sdf_all[alive, c0:c1] = sdf
        tau[alive] += (sig * deltas[alive, c0:c1]).sum(-1)
        alive = alive[tau[alive] < stop_tau]
        if alive.numel() == 0:
            break
    return render_weights(sigma, deltas), sdf_all
