"""How much of a light reaches the sensor: emission pattern, distance, extinction, unit tolerance.

Two beacon models (:class:`~deckpose.render.leds_config.LedModel`):

* ``disc`` (default; the frames of earlier versions): a flat emitting disc of radius
  ``r`` and constant radiance, so its light on the sensor is the radiance times its
  projected area, ``flux = peak * intensity * pi r^2 |det J|`` (``J`` the local
  Jacobian of the projection, px per metre of deck). A constant-radiance disc is a
  Lambertian emitter; the inverse square of the distance is in ``|det J|``.
* ``point``: an LED of on-axis intensity ``I0`` and pattern ``I(theta) = I0 cos(theta)**m``,
  ``theta`` the angle between the deck normal and the line to the camera. A lens of
  aperture area ``A`` at distance ``d`` collects ``I(theta) A cos(phi) / d^2``, ``phi``
  the angle of the ray from the optical axis (the aperture seen obliquely). ``I0`` is
  set so that, on the optical axis and facing the camera, both models give the same
  light: ``flux = peak * intensity * pi r^2 fx fy cos(theta)**m cos(phi) / d^2``.

Both are multiplied by the atmosphere's Beer–Lambert transmission ``exp(-3.912 d / V)``
(Koschmieder's law for a visibility ``V``) and by each unit's intensity factor, drawn
once per dataset from U(1 - t, 1) so a beacon keeps its brightness in every frame
(LED binning and ageing), and the bow beacon by ``bow_intensity``. The flux actually
drawn is recorded per beacon (``spot_flux_e`` in ``beacons.parquet``), so the centroid
bound stays exact whatever the model.
"""

from __future__ import annotations

import numpy as np
from deckpose.render.leds_config import LedModel, LedSpec
from deckpose.render.sensor_config import SensorSpec
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout

#: Stream index of the unit factors in ``SeedSequence([config seed, stream])``.
UNIT_FACTOR_STREAM = 3


def unit_factors(layout: DeckLayout, leds: LedSpec, seed: int) -> NDArray[np.float64]:
    """Each beacon's intensity factor, U(1 - tolerance, 1), times ``bow_intensity`` for the bow.

    Parameters
    ----------
    layout : DeckLayout
    leds : LedSpec
    seed : int
        The config's seed (the factors are the dataset's, not a frame's).

    Returns
    -------
    (N,) array of float
        One factor per beacon id; all ones for the defaults.
    """
    out = np.ones(layout.n_beacons)
    if leds.intensity_tolerance > 0:
        rng = np.random.default_rng(np.random.SeedSequence([seed, UNIT_FACTOR_STREAM]))
        out = rng.uniform(1.0 - leds.intensity_tolerance, 1.0, layout.n_beacons)
    out[list(layout.bow_ids)] *= leds.bow_intensity
    return out


def transmission(distance_m: NDArray[np.float64], leds: LedSpec) -> NDArray[np.float64]:
    """Beer–Lambert transmission of the air over ``distance_m`` (Koschmieder extinction)."""
    return np.exp(-leds.extinction_per_m() * np.asarray(distance_m, float))


def point_light_gain(P_cam: NDArray[np.float64], normal_cam: NDArray[np.float64] | None,
                     camera: CameraModel, exponent: float) -> NDArray[np.float64]:
    """``fx fy cos(theta)**m cos(phi) / d^2`` of point lights at ``P_cam``: px^2 per m^2 of emitter.

    Parameters
    ----------
    P_cam : (N, 3) array of float
        The lights in the camera frame, metres.
    normal_cam : (3,) or (N, 3) array of float, or None
        The emitters' axis in the camera frame (the deck normal), one for all or one per
        light; None: isotropic.
    camera : CameraModel
    exponent : float
        ``m`` of the emission pattern (ignored when ``normal_cam`` is None).
    """
    P = np.asarray(P_cam, float)
    d = np.linalg.norm(P, axis=1)
    cos_phi = np.clip(P[:, 2] / d, 0.0, 1.0)
    gain = camera.fx * camera.fy * cos_phi / (d * d)
    if normal_cam is not None:
        cos_theta = np.clip(-(P * np.asarray(normal_cam, float)).sum(axis=-1) / d, 0.0, 1.0)
        gain = gain * cos_theta ** exponent
    return gain


def beacon_flux(layout: DeckLayout, camera: CameraModel, sensor: SensorSpec, leds: LedSpec,
                J: NDArray[np.float64], P_cam: NDArray[np.float64],
                normal_cam: NDArray[np.float64]) -> NDArray[np.float64]:
    """Light of each beacon on the sensor at one pose, radiance x pixels (before unit factors).

    Parameters
    ----------
    layout : DeckLayout
    camera : CameraModel
    sensor : SensorSpec
        ``beacon_peak`` (radiance of a beacon of intensity 1).
    leds : LedSpec
    J : (N, 2, 2) array of float
        Projection Jacobians at the beacons, px per metre of deck (``disc`` model).
    P_cam : (N, 3) array of float
        Beacon centres in the camera frame, metres.
    normal_cam : (3,) or (N, 3) array of float
        The deck normal in the camera frame (one per beacon where the poses differ).

    Returns
    -------
    (N,) array of float
        Core plus halo light of each beacon; NaN or 0 where it is not seen.
    """
    r = layout.beacon_radius_m
    radiance = sensor.beacon_peak * layout.intensity
    if leds.model is LedModel.DISC:  # (the product in this order: earlier versions' frames, bit for bit)
        flux = radiance * (np.pi * r * r * np.abs(np.linalg.det(J)))
    else:
        flux = radiance * (np.pi * r * r * point_light_gain(P_cam, normal_cam, camera, leds.emission_exponent))
    return flux * transmission(np.linalg.norm(P_cam, axis=1), leds)
