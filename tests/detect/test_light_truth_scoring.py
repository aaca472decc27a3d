"""Fair scoring under lateral colour: the benchmark's truth is the light's centroid in the channel sum.

Each expected value is computed here again: the channel sum of an image drawn in the test
(three Gaussian spots of known centres and electrons, one per channel) and its intensity
centroid by brute force; and, through the renderer's lens (``through_lens``), the centroid
of the exposed, noise-free channel sum of each beacon against the truth the benchmark
builds from the recorded ``u_r_px ... spot_flux_b_e`` columns.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from deckpose.detect.benchmark import channel_sum_centre_px, match_frame, summarise
from deckpose.render.beacons import Splat, beacon_splats
from deckpose.render.config import OpticsSpec, SensorSpec
from deckpose.render.optics import optics_row, through_lens
from deckpose.render.sensor import expose

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose
from deckpose.projection import project_layout

CENTRES = {"r": (40.3, 31.7), "g": (41.1, 30.2), "b": (42.6, 29.4)}  # px, per channel
FLUX_E = {"r": 5000.0, "g": 2000.0, "b": 1000.0}


def _gauss(shape: tuple[int, int], centre: tuple[float, float], sigma: float, flux: float) -> np.ndarray:
    v, u = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    q = ((u - centre[0]) ** 2 + (v - centre[1]) ** 2) / (2 * sigma * sigma)
    return flux * np.exp(-q) / (2 * math.pi * sigma * sigma)


def _centroid(img: np.ndarray) -> np.ndarray:
    v, u = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    return np.array([(img * u).sum(), (img * v).sum()]) / img.sum()


def _row(**extra: float) -> pd.DataFrame:
    g = CENTRES["g"]
    return pd.DataFrame([{
        "frame_id": 0, "beacon_id": 0, "u_px": g[0], "v_px": g[1], "visible": True, "apparent_radius_px": 2.0,
        "u_r_px": CENTRES["r"][0], "v_r_px": CENTRES["r"][1], "u_b_px": CENTRES["b"][0], "v_b_px": CENTRES["b"][1],
        "spot_flux_r_e": FLUX_E["r"], "spot_flux_g_e": FLUX_E["g"], "spot_flux_b_e": FLUX_E["b"], **extra}])


def test_truth_is_the_centroid_of_a_drawn_channel_sum() -> None:
    # three Gaussians (sigma 1.5 px, 30 sigma of room) summed as a channel-sum detector sums them;
    # a sampled Gaussian's centroid is its centre to ~exp(-2 pi^2 sigma^2) ~ 1e-19 px, the float
    # sums to ~1e-12: 1e-9 px is a tolerance nothing but a wrong weighting can fail
    img = sum(_gauss((64, 84), CENTRES[c], 1.5, FLUX_E[c]) for c in "rgb")
    want = _centroid(np.asarray(img))
    got = channel_sum_centre_px(_row())[0]
    np.testing.assert_allclose(got, want, atol=1e-9)
    # it is not the green centre (the lens moved the light by ~0.8 px here)
    assert np.hypot(*(got - np.array(CENTRES["g"]))) > 0.5


def test_without_channel_columns_or_light_the_truth_is_the_projected_centre() -> None:
    plain = _row().drop(columns=["spot_flux_r_e", "spot_flux_g_e", "spot_flux_b_e"])
    np.testing.assert_array_equal(channel_sum_centre_px(plain), plain[["u_px", "v_px"]].to_numpy())
    unlit = _row(spot_flux_r_e=float("nan"))  # NaN: no spot drawn (or optics off)
    np.testing.assert_array_equal(channel_sum_centre_px(unlit), unlit[["u_px", "v_px"]].to_numpy())
    # no chromatic shift: exactly the green centre, whatever the fluxes (no round-off from the weighting)
    same = _row(u_r_px=CENTRES["g"][0], v_r_px=CENTRES["g"][1], u_b_px=CENTRES["g"][0], v_b_px=CENTRES["g"][1])
    np.testing.assert_array_equal(channel_sum_centre_px(same), same[["u_px", "v_px"]].to_numpy())


def test_matching_scores_the_light_and_keeps_the_geometric_error() -> None:
    gt = _row()
    img = sum(_gauss((64, 84), CENTRES[c], 1.5, FLUX_E[c]) for c in "rgb")
    light = _centroid(np.asarray(img))
    d = np.array([0.03, -0.04])  # a detector's own error
    det = pd.DataFrame({"frame_id": [0], "beacon_id": [0], "u_px": [light[0] + d[0]], "v_px": [light[1] + d[1]],
                        "size_px": [1.5]})
    m = match_frame(det, gt)
    assert bool(m["matched"].iloc[0])
    np.testing.assert_allclose(m[["du_px", "dv_px"]].to_numpy()[0], d, atol=1e-9)
    geo = light + d - np.array(CENTRES["g"])
    np.testing.assert_allclose(m[["du_geo_px", "dv_geo_px"]].to_numpy()[0], geo, atol=1e-9)
    m["camera"], m["camera_height_m"], m["occluded"] = "c", 30.0, False
    frames = pd.DataFrame({"frame_id": [0], "camera_height_m": [30.0]})
    fout = pd.DataFrame({"frame_id": [0], "ok": [True], "seconds": [0.01], "cpu_seconds": [0.01]})
    s = summarise("x", m, det, fout, frames).iloc[0]
    assert s["rms_px"] == pytest.approx(math.sqrt((d @ d) / 2), rel=1e-9)
    assert s["rms_geometric_px"] == pytest.approx(math.sqrt((geo @ geo) / 2), rel=1e-9)


CAMERA = CameraModel(640, 480, [[600.0, 0, 321.3], [0, 600.0, 238.6], [0, 0, 1]])
SENSOR = SensorSpec(bit_depth=16, noise=False, beacon_peak=0.6, full_well_e=1e6)  # no clipping, no noise


# red and blue moved unequally: for a white spot equal and opposite shifts would cancel in the
# channel sum (only the red bow would show the difference); these move every ring beacon
@pytest.mark.parametrize("ppm", [(4000.0, -1000.0), (-2000.0, 5000.0)])
def test_recorded_channel_fluxes_place_the_light_the_lens_drew(ppm: tuple[float, float]) -> None:
    """Through the renderer's lens: the drawn channel sum's centroid is the benchmark's truth."""
    layout = DeckLayout()
    ship = ShipPose(math.radians(4.0), math.radians(-3.0), math.radians(20.0), 0.8, 0.6, -0.4)
    pose = CameraPose.nadir(40.0)
    optics = OpticsSpec(f_number=2.0, pixel_pitch_um=2.0, diffraction=True, lateral_ca_ppm=ppm)
    proj = project_layout(layout, ship, pose, CAMERA)
    base = beacon_splats(layout, (ship,), pose, CAMERA, SENSOR)
    raster = np.zeros((CAMERA.height_px, CAMERA.width_px, 3), np.uint8)
    scale = np.ones(3, np.float32)
    lens = through_lens(optics, CAMERA, SENSOR, raster, scale, base, [], proj.points_px, proj.depth_m,
                        np.zeros(0))
    rows = pd.DataFrame([{"u_px": proj.points_px[i, 0], "v_px": proj.points_px[i, 1], "spot_flux_e":
                          lens.spots.flux_e[i], **optics_row(lens.record, i)} for i in range(len(proj.points_px))])
    truth = channel_sum_centre_px(rows)
    checked = 0
    for sp in lens.beacons:
        one: list[Splat] = [sp]
        img = expose(raster, scale, one, SENSOR, np.random.default_rng(0)).astype(float)
        i = sp.beacon_id
        # the channel fluxes add up to the recorded spot flux
        f = rows.loc[i, ["spot_flux_r_e", "spot_flux_g_e", "spot_flux_b_e"]].to_numpy(float)
        assert f.sum() == pytest.approx(rows.loc[i, "spot_flux_e"], rel=1e-12)
        got = _centroid(img.sum(axis=2))
        # the exposed image is rounded to whole DN (peak ~4e4 DN): the centroid of a spot of
        # ~2e5 DN moves by at most ~sqrt(n) 0.29 DN x r / flux ~ 1e-4 px; 2e-3 px also leaves the
        # halo's truncation at the window edge (< 1e-3 of the light, point-symmetric) room
        np.testing.assert_allclose(got, truth[i], atol=2e-3)
        # and the lens moved it measurably off the geometric centre (scoring the green would be wrong)
        if np.hypot(*(truth[i] - proj.points_px[i])) > 0.05:
            assert np.hypot(*(got - proj.points_px[i])) > 0.04
            checked += 1
    assert checked >= 6
