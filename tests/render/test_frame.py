"""Whole frames: motion blur, PBR shading and the ground truth attached to a frame."""

from __future__ import annotations

import dataclasses

import numpy as np
from deckpose.render.config import Lighting, Shading
from deckpose.render.frame import render_frame
from deckpose.render.plan import FrameSpec

from deckpose.pose import ShipPose
from deckpose.projection import project_layout

from .conftest import tiny_config


def _spot_moments(img: np.ndarray, u: float, v: float, half: int = 9) -> tuple[np.ndarray, np.ndarray]:
    r0, c0 = round(v) - half, round(u) - half
    win = img[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1].astype(float)
    vv, uu = np.mgrid[r0: r0 + 2 * half + 1, c0: c0 + 2 * half + 1]
    m = np.array([(win * uu).sum(), (win * vv).sum()]) / win.sum()
    var = np.array([(win * (uu - m[0]) ** 2).sum(), (win * (vv - m[1]) ** 2).sum()]) / win.sum()
    return m, var


def test_motion_blur_streaks_along_the_motion_and_stays_centred(egl_renderer_factory) -> None:
    """Yawing the deck during the exposure streaks a port beacon along v; its centroid lies on the
    mean position over the exposure."""
    cfg = tiny_config()
    cfg = dataclasses.replace(cfg, sensor=dataclasses.replace(cfg.sensor, noise=False, bit_depth=16,
                                                              beacon_peak=2.0, halo_fraction=0.0))  # unsaturated
    cam = cfg.cameras_by_name()["4mp-320x240"]
    mid = ShipPose()
    blur = tuple(ShipPose(yaw_rad=y) for y in np.linspace(-0.08, 0.08, 9))
    r = egl_renderer_factory(cfg)
    dark = dataclasses.replace(cfg, layout=dataclasses.replace(cfg.layout, intensity=1e-12))

    def beacon_light(c, poses):  # the frame minus the same frame with beacons off
        spec = FrameSpec(0, cam.name, 40.0, mid, poses, 0.0, Lighting.NIGHT, 1)
        on, off = render_frame(c, spec, cam, r), render_frame(dark, spec, cam, r)
        return on, on.frame.image.astype(float).sum(axis=2) - off.frame.image.astype(float).sum(axis=2)

    sharp, sharp_img = beacon_light(cfg, ())
    blurred, blurred_img = beacon_light(cfg, blur)
    u, v = project_layout(cfg.layout, mid, sharp.truth.camera_pose, cam).points_px[3]  # port, image left
    m_s, var_s = _spot_moments(sharp_img, u, v)
    m_b, var_b = _spot_moments(blurred_img, u, v)
    assert var_b[1] > 3 * var_s[1]  # yaw moves the port beacon along image v
    assert abs(var_b[0] - var_s[0]) < 0.1 * var_s[0]  # across the streak: as wide as the sharp spot
    # the streak's centroid is the mean of the exposure's positions (an arc: its sagitta puts it
    # ~0.06 px inside the mid-exposure point, which the ground truth reports)
    arc = np.mean([project_layout(cfg.layout, p, sharp.truth.camera_pose, cam).points_px[3] for p in blur], axis=0)
    np.testing.assert_allclose(m_b - m_s, arc - np.array([u, v]), atol=0.01)
    np.testing.assert_allclose(blurred.truth.points_px[3], [u, v])


def test_pbr_day_render_and_truth(egl_renderer_factory) -> None:
    cfg = tiny_config(scene={"shading": "pbr", "texture_px": 256})
    assert cfg.scene.shading is Shading.PBR
    cam = cfg.cameras_by_name()["4mp-320x240"]
    ship = ShipPose(0.05, -0.02, 0.2, 0.4)
    rf = render_frame(cfg, FrameSpec(3, cam.name, 30.0, ship, (), 1.5, Lighting.DAY, 9), cam,
                      egl_renderer_factory(cfg))
    img = rf.frame.image
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8 and not img.flags.writeable
    assert 30 < img.mean() < 220  # lit, not black or blown out
    assert rf.frame.stamp_ns == 1_500_000_000 and rf.truth.seed == 9
    want = project_layout(cfg.layout, ship, rf.truth.camera_pose, cam)
    np.testing.assert_array_equal(rf.truth.points_px, want.points_px)
    assert rf.truth.visible.all()
