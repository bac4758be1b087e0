"""Tracking a frame whose exposure changed (gain 0.6, bias +0.12 against the frames the map was
fitted to): with the affine brightness term the pose is recovered and the fitted gain and bias
are the change; without it the pose stays pulled off (synthetic room, map fitted with GT poses).

Measured on this map from a ~4 cm, ~1.5 deg start: Adam 2.3 cm off -> 1.3 cm on; Gauss-Newton
2.7 cm off -> 0.6 cm on."""
import math
from dataclasses import replace

import pytest
import torch

from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.losses.brightness import apply_brightness
from nicer_stream.tracking.tracker import Tracker

GAIN, BIAS = 0.6, 0.12  # darker and lifted: no colour leaves [0, 1]
START = torch.tensor([0.03, -0.02, 0.02, 0.02, -0.015, 0.01])  # ~4 cm, ~1.5 deg


def _brightened(mf):
    out = replace(mf, rgb=apply_brightness(mf.rgb, torch.tensor([math.log(GAIN), BIAS])))
    assert 0.0 <= float(out.rgb.min()) and float(out.rgb.max()) <= 1.0
    return out


def _track(fitted, tracking, frame, T_init):
    cfg, _, _, _, model, beta = fitted
    torch.manual_seed(0)  # the renders' jitter
    return Tracker(model, beta, tracking, cfg.render).track(frame, T_init)


@pytest.mark.parametrize("optimizer,iters", [("adam", 40), ("gauss_newton", 8)])
def test_tracking_through_an_exposure_change_needs_the_brightness_term(fitted, pose_error, optimizer, iters):
    cfg, frames, mfs, poses, _, _ = fitted
    T_gt = poses[frames[4].index]
    T_init = T_gt @ se3_exp(START)
    frame = _brightened(mfs[4])
    tc = replace(cfg.tracking, optimizer=optimizer, iters=iters, affine_brightness=False)
    off = _track(fitted, tc, frame, T_init)
    on = _track(fitted, replace(tc, affine_brightness=True), frame, T_init)
    (t0, r0), (t_off, r_off), (t_on, r_on) = (pose_error(T_gt, T) for T in (T_init, off.T_world_cam, on.T_world_cam))
    print(optimizer, "start", t0, r0, "off", t_off, r_off, "on", t_on, r_on, on.brightness)
    assert off.brightness is None and on.brightness is not None
    assert t_on < 0.5 * t0 and r_on < 0.5 * r0, (t0, t_on, r0, r_on)
    assert t_on < 0.75 * t_off, (t_off, t_on)


def test_tracking_fits_the_exposure_change(fitted):
    """The gain and bias fitted to the brightened frame are the change applied to the gain and
    bias fitted to the frame itself (the map's render is blurrier than the images, so neither
    is (0, 0) on its own)."""
    cfg, frames, mfs, poses, _, _ = fitted
    T_gt = poses[frames[4].index]
    tc = replace(cfg.tracking, optimizer="gauss_newton", iters=4, affine_brightness=True)
    a0, b0 = _track(fitted, tc, mfs[4], T_gt).brightness
    a1, b1 = _track(fitted, tc, _brightened(mfs[4]), T_gt).brightness
    print("own", a0, b0, "brightened", a1, b1)
    assert abs(math.exp(a1 - a0) - GAIN) < 0.03, math.exp(a1 - a0)
    assert abs(b1 - (GAIN * b0 + BIAS)) < 0.02, (b1, GAIN * b0 + BIAS)
