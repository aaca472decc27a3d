"""The batched render paths against the plain computations they replace.

* :func:`deckpose.render.psf_kernels.full_convolution` (the Fourier path from
  ``FFT_RADIUS_PX``, ``filter2D`` below it) against ``scipy.signal.convolve2d`` in float64;
* :func:`deckpose.render.split_kernels.through_parts` (the wide kernel applied once for the three
  channels) against each channel's whole kernel, composed first, in float64;
* :func:`deckpose.render.beacons.splats_under` (each beacon under its own transforms, in one batch)
  against :func:`deckpose.render.beacons.beacon_splats` called for each beacon alone with its own poses;
* :func:`deckpose.render.beacons.spot_splat` (the cores drawn on their own window) against the sum
  of every sub-pose's core and halo drawn on the whole window in float64.

Tolerances: float32 round-off, ~1e-7 of a window's largest value (the inputs are float32).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from deckpose.render.beacons import beacon_splats, splats_under, spot_splat
from deckpose.render.config import OpticsSpec, SensorSpec
from deckpose.render.emitter import dome_light_centroids
from deckpose.render.leds_config import EmitterShape, LedModel, LedSpec
from deckpose.render.optics import kernel_parts
from deckpose.render.psf_kernels import FFT_RADIUS_PX, full_convolution
from deckpose.render.split_kernels import KernelParts, compose_parts, through_parts
from scipy.signal import convolve2d

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose, T_cam_from_deck
from deckpose.projection import project_layout

CAMERA = CameraModel(1920, 1080, [[1500.0, 0, 960.3], [0, 1500.0, 539.6], [0, 0, 1]])
RNG_SEED = 7


def _direct(image: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """Full convolution in float64, channel by channel."""
    img = image.astype(np.float64)
    if img.ndim == 2:
        return convolve2d(img, kernel, mode="full")
    return np.stack([convolve2d(img[..., c], kernel, mode="full") for c in range(img.shape[-1])], axis=-1)


@pytest.mark.parametrize("radius", [1, 5, FFT_RADIUS_PX - 1, FFT_RADIUS_PX, 24])
@pytest.mark.parametrize("shape", [(31, 31), (17, 40), (23, 23, 4)])
def test_full_convolution_is_the_direct_sum(radius: int, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(RNG_SEED)
    image = rng.random(shape).astype(np.float32)
    kernel = rng.random((2 * radius + 1,) * 2)
    kernel[radius, radius + 1] += 3.0  # not symmetric: a flipped kernel would show
    got = full_convolution(image, kernel)
    want = _direct(image, kernel)
    assert got.shape == want.shape and got.dtype == np.float32
    assert np.abs(got - want).max() <= 1e-6 * np.abs(want).max()


def _parts(glare: float, ca_ppm: float) -> KernelParts:
    optics = OpticsSpec(f_number=2.8, focus_distance_m=15.0, diffraction=True, glare_fraction=glare,
                        glare_radius_px=3.0, lateral_ca_ppm=(ca_ppm, -ca_ppm), field_blur_px=1.2)
    return kernel_parts(optics, CAMERA, 30.0, np.array([1700.0, 900.0]))  # off-axis: CA shifts and field blur


@pytest.mark.parametrize(("glare", "ca_ppm"), [(0.0, 0.0), (0.03, 0.0), (0.03, 900.0), (0.0, 900.0)])
@pytest.mark.parametrize("channels", [None, 4])
def test_through_parts_is_each_composed_kernel(glare: float, ca_ppm: float, channels: int | None) -> None:
    parts = _parts(glare, ca_ppm)
    if glare > 0:
        assert parts.wide is not None and parts.wide.shape[0] // 2 >= FFT_RADIUS_PX  # the Fourier path is taken
    if ca_ppm > 0:
        assert np.abs(parts.shifts_px).max() > 0.5  # the shift moves light by more than half a pixel
    rng = np.random.default_rng(RNG_SEED)
    window = rng.random((21, 21) if channels is None else (21, 21, channels)).astype(np.float32)
    got = through_parts(window, parts)
    for c, kernel in enumerate(compose_parts(parts)):
        want = _direct(window, kernel)
        assert got[c].shape == want.shape
        assert np.abs(got[c] - want).max() <= 1e-6 * np.abs(want).max(), f"channel {c}"


def test_from_kernels_applies_the_kernels_whole() -> None:
    rng = np.random.default_rng(RNG_SEED)
    kernels = tuple(rng.random((2 * r + 1, 2 * r + 1)) for r in (1, 2, 3))
    window = rng.random((15, 15)).astype(np.float32)
    got = through_parts(window, KernelParts.from_kernels((kernels[0], kernels[1], kernels[2])))
    for c in range(3):
        want = _direct(window, np.pad(kernels[c], 3 - (c + 1)))  # composed to one radius, as the parts say
        assert np.abs(got[c] - want).max() <= 1e-6 * np.abs(want).max()


SENSOR = SensorSpec(psf_sigma_px=1.1, halo_fraction=0.05, halo_scale=4.0)


def test_domed_beacons_are_lit_where_each_sub_pose_puts_them() -> None:
    """A domed beacon's centre is the mean of its light centroids at its own sub-poses,
    each from :func:`dome_light_centroids` under that one transform (the (4, 4) form)."""
    cam_pose = CameraPose.nadir(25.0)
    k = 3
    T = np.stack([np.stack([T_cam_from_deck(p, cam_pose) for p in _poses(i, k)]) for i in range(LAYOUT.n_beacons)])
    leds = LedSpec(emitter=EmitterShape.DOME)
    splats = splats_under(LAYOUT, T, CAMERA, SENSOR, leds)
    assert len(splats) == LAYOUT.n_beacons
    for sp in splats:
        i = sp.beacon_id
        want = np.mean([dome_light_centroids(LAYOUT, T[i, j], CAMERA)[i] for j in range(k)], axis=0)
        np.testing.assert_allclose(sp.centre_px, want, rtol=0, atol=1e-9)
        flat = np.mean([project_layout(LAYOUT, p, cam_pose, CAMERA).points_px[i] for p in _poses(i, k)], axis=0)
        assert 0.01 < np.linalg.norm(want - flat) < 5  # the dome's centroid is not the projected centre
LAYOUT = DeckLayout()


def _poses(i: int, k: int) -> tuple[ShipPose, ...]:
    """Beacon ``i``'s own k sub-poses: each beacon moves differently (as under a rolling shutter)."""
    return tuple(ShipPose(0.02 + 0.003 * i + 0.001 * j, -0.01 * i, 0.05 * j, 0.1 * j, 0.02 * i, -0.03 * j)
                 for j in range(k))


@pytest.mark.parametrize("k", [1, 5])
@pytest.mark.parametrize("leds", [LedSpec(), LedSpec(model=LedModel.POINT, emission_exponent=6.0, visibility_km=0.5),
                                  LedSpec(emitter=EmitterShape.DOME)])
def test_splats_under_each_beacons_own_transforms(k: int, leds: LedSpec) -> None:
    cam_pose = CameraPose.nadir(25.0)
    T = np.stack([np.stack([T_cam_from_deck(p, cam_pose) for p in _poses(i, k)]) for i in range(LAYOUT.n_beacons)])
    factors = np.linspace(0.6, 1.4, LAYOUT.n_beacons)
    batch = {sp.beacon_id: sp for sp in splats_under(LAYOUT, T, CAMERA, SENSOR, leds, factors)}
    assert len(batch) == LAYOUT.n_beacons
    for i in range(LAYOUT.n_beacons):
        alone = [sp for sp in beacon_splats(LAYOUT, _poses(i, k), cam_pose, CAMERA, SENSOR, leds, factors)
                 if sp.beacon_id == i]
        assert len(alone) == 1
        a, b = alone[0], batch[i]
        assert (a.row0, a.col0, a.patch.shape) == (b.row0, b.col0, b.patch.shape)
        np.testing.assert_allclose(b.centre_px, a.centre_px, rtol=0, atol=1e-9)
        np.testing.assert_allclose(b.cov_px2, a.cov_px2, rtol=1e-9)
        assert b.core_flux == pytest.approx(a.core_flux, rel=1e-12)
        assert np.abs(b.patch - a.patch).max() <= 1e-6 * a.patch.max()


def _elongated(ratio: float) -> np.ndarray:
    c, s = np.cos(0.6), np.sin(0.6)
    R = np.array([[c, -s], [s, c]])
    return R @ np.diag([(0.8 * ratio) ** 2, 0.8 ** 2]) @ R.T


SUB_POSES = {
    "near round": ([(500.3, 400.7), (501.1, 401.2), (502.4, 401.9)],
                   [np.array([[2.0, 0.4], [0.4, 1.3]]) * (1 + 0.1 * j) for j in range(3)]),
    # seven sub-poses at one place and the eighth 30 px away (a jolt): the mean is far from the middle
    "lopsided": ([(900.3, 500.6)] * 7 + [(930.3, 500.6)], [0.64 * np.eye(2)] * 8),
    "elongated": ([(700.2, 300.9), (700.9, 301.3)], [_elongated(25.0)] * 2),
}


@pytest.mark.parametrize("case", list(SUB_POSES))
def test_spot_splat_is_every_gaussian_on_the_whole_window(case: str) -> None:
    centres = [np.array(c) for c in SUB_POSES[case][0]]
    covs = SUB_POSES[case][1]
    comps = [(c, cv, 5000.0 * (1 + 0.2 * j)) for j, (c, cv) in enumerate(zip(centres, covs))]
    sp = spot_splat(comps, (1.0, 1.0, 1.0), SENSOR, CAMERA)
    assert sp is not None
    n = sp.patch.shape[0]
    want = np.zeros((n, n))
    v, u = np.mgrid[sp.row0:sp.row0 + n, sp.col0:sp.col0 + n].astype(float)
    h, s2 = SENSOR.halo_fraction, SENSOR.halo_scale ** 2
    for c, cv, f in comps:
        for frac, scale in ((1.0 - h, 1.0), (h, s2)):
            C = cv * scale
            inv = np.linalg.inv(C)
            du, dv = u - c[0], v - c[1]
            q = inv[0, 0] * du * du + 2 * inv[0, 1] * du * dv + inv[1, 1] * dv * dv
            want += frac * f / len(comps) * np.exp(-0.5 * q) / (2 * math.pi * math.sqrt(np.linalg.det(C)))
    assert np.abs(sp.patch - want).max() <= 1e-6 * want.max()
    # every sub-pose's core lies inside the window (8 of its sigmas)
    sd = math.sqrt(max(np.linalg.eigvalsh(cv)[-1] for cv in covs))
    for c in centres:
        assert sp.col0 <= c[0] - 8 * sd and c[0] + 8 * sd <= sp.col0 + n - 1
        assert sp.row0 <= c[1] - 8 * sd and c[1] + 8 * sd <= sp.row0 + n - 1
    # the core window is smaller than the halo's: the truncation is exercised
    assert n > 2 * math.ceil(8.0 * sd + 3)


@pytest.mark.parametrize("shape", [(16, 16), (15, 17), (15,)])
def test_full_convolution_refuses_a_kernel_without_a_centre(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="odd side"):
        full_convolution(np.zeros((20, 20), np.float32), np.ones(shape))
