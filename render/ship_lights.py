"""Lights in the frame that are not beacons: navigation lights, deck floodlights, sea glints.

A detector benchmark that counts false detections needs lights that are not beacons,
at known places. The ship's lights sit on a notional hull around the helideck, in the
deck frame (x bow, y port, z up; the deck plate's half side ``h``, its freeboard
``f`` above the sea):

* ``port`` (red) and ``starboard`` (green) sidelights on the bridge wings,
  ``(h + 8, +-(h - 2), 4)`` m; the white ``masthead`` light ``(h + 14, 0, 12)`` m;
  the white ``stern`` light at the transom, ``(-h - 0.5, 0, -1)`` m;
* ``floodlight`` (warm white) on poles ``1.5`` m high, evenly spaced along the deck's edge;
* ``glint`` (white): the sun or moon mirrored by a facet of the sea (world-fixed, on the
  sea's mean plane ``z = -f``), and ``deck_glint`` (white): mirrored by the water film of a
  wet deck (on the plate, moving with the deck); each drawn per frame from the frame's seed
  as :mod:`deckpose.render.glints` places them: facets of random slope, each where it
  mirrors the light into the camera, so they gather around the mirror point of the sea or
  the deck, as sun glitter does, and only those in the image are kept. The light is the
  scene's sun (:data:`deckpose.render.scene.SUN_TRAVEL_WORLD`), at night read as the moon.

Each is a point source of isotropic intensity ``intensity`` (``glint_intensity``) times
that of an on-axis beacon (:func:`deckpose.render.light.point_light_gain`), through the
same atmosphere, drawn as a PSF-sized spot with the beacons' halo. Real sidelights
shine sideways; seen from above they would be dimmer: ``intensity`` sets how bright
they look. Every light in front of the camera is recorded (``lights.parquet``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh
from deckpose.render.beacons import Splat, spot_splat
from deckpose.render.glints import cox_munk_slope_sigma, glint_points
from deckpose.render.leds_config import LedSpec
from deckpose.render.light import point_light_gain, transmission
from deckpose.render.scene_config import ShipModelSpec
from deckpose.render.sensor_config import SensorSpec
from deckpose.render.ship_lights_config import ShipLightsSpec
from deckpose.render.ship_model import hull_mesh, joined_mesh, superstructure_mesh
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.pose import CameraPose, ShipPose

#: Stream index of the glints in ``SeedSequence([frame seed, stream])``.
GLINT_STREAM = 2

_RED = (1.0, 0.08, 0.05)
_GREEN = (0.05, 1.0, 0.3)
_WHITE = (1.0, 1.0, 1.0)
_WARM = (1.0, 0.85, 0.6)


@dataclass(frozen=True)
class ShipLight:
    """One non-beacon light.

    Attributes
    ----------
    kind : str
        ``port``, ``starboard``, ``masthead``, ``stern``, ``floodlight``, ``glint`` or ``deck_glint``.
    position_m : (3,) array of float
        Position in the deck frame (``on_deck``) or the world frame (sea glints), metres.
    on_deck : bool
        Whether it moves with the deck.
    rgb : (3,) floats
    intensity : float
        Relative to an on-axis beacon of the layout.
    """

    kind: str
    position_m: NDArray[np.float64]
    on_deck: bool
    rgb: tuple[float, float, float]
    intensity: float


def ship_lights(spec: ShipLightsSpec, deck_half_size_m: float, freeboard_m: float,
                rng: np.random.Generator, *, ship: ShipPose, camera_pose: CameraPose, camera: CameraModel,
                to_light_world: NDArray[np.float64], ship_model: ShipModelSpec = ShipModelSpec()
                ) -> list[ShipLight]:
    """The frame's non-beacon lights, light id = list index.

    Parameters
    ----------
    spec : ShipLightsSpec
    deck_half_size_m : float
        Half the deck plate's side, metres.
    freeboard_m : float
        Height of the deck above the sea, metres.
    rng : numpy.random.Generator
        The frame's glint stream (unused without glints).
    ship : ShipPose
        The deck's pose at mid-exposure (where the wet deck mirrors the light).
    camera_pose : CameraPose
    camera : CameraModel
        Where the glints must be seen from, and in which image.
    to_light_world : (3,) array of float
        Unit direction toward the sun or moon that the water mirrors.
    ship_model : ShipModelSpec
        The hull and superstructure in the scene, which hide glints behind them (the deck
        plate always does).
    """
    h, k = deck_half_size_m, spec.intensity
    out: list[ShipLight] = []
    if spec.navigation:
        out += [ShipLight("port", np.array([h + 8.0, h - 2.0, 4.0]), True, _RED, k),
                ShipLight("starboard", np.array([h + 8.0, -(h - 2.0), 4.0]), True, _GREEN, k),
                ShipLight("masthead", np.array([h + 14.0, 0.0, 12.0]), True, _WHITE, k),
                ShipLight("stern", np.array([-h - 0.5, 0.0, -1.0]), True, _WHITE, k)]
    for j in range(spec.floodlights):
        t = 8.0 * (j + 0.5) / spec.floodlights  # perimeter of the square, in half-sides
        side, a = int(t // 2), (t % 2) - 1.0
        x, y = [(h, a * h), (-a * h, h), (-h, -a * h), (a * h, -h)][side]
        out.append(ShipLight("floodlight", np.array([x, y, 1.5]), True, _WARM, k))
    if not (spec.glints or spec.deck_glints):
        return out
    R, t_deck = ship.R_world_from_deck, ship.t_world_from_deck
    blocker = ship_occluder(h, freeboard_m, ship_model)
    blocker.apply_transform(ship.T_world_from_deck)
    sea = glint_points(spec.glints, cox_munk_slope_sigma(spec.wind_m_per_s), np.eye(3),
                       np.array([0.0, 0.0, -freeboard_m]), to_light_world, camera_pose, camera, rng,
                       occluder_world=blocker)
    out += [ShipLight("glint", p, False, _WHITE, spec.glint_intensity) for p in sea]
    deck = glint_points(spec.deck_glints, math.tan(math.radians(spec.deck_slope_deg)), R, t_deck,
                        to_light_world, camera_pose, camera, rng, half_extent_m=h, occluder_world=blocker)
    out += [ShipLight("deck_glint", (p - t_deck) @ R, True, _WHITE, spec.glint_intensity) for p in deck]
    return out


def ship_occluder(deck_half_size_m: float, freeboard_m: float, ship_model: ShipModelSpec) -> trimesh.Trimesh:
    """What hides a glint from the camera, deck frame, metres.

    Parameters
    ----------
    deck_half_size_m : float
        Half the deck plate's side: the plate (two triangles at deck z = 0) always hides.
    freeboard_m : float
        Deck height above the sea (the hull's depth).
    ship_model : ShipModelSpec
        The hull and superstructure where the scene draws them.
    """
    a = deck_half_size_m
    plate = trimesh.Trimesh(np.array([[-a, -a, 0.0], [a, -a, 0.0], [a, a, 0.0], [-a, a, 0.0]]),
                            np.array([[0, 1, 2], [0, 2, 3]]), process=False)
    parts = [plate]
    if ship_model.hull:
        parts.append(hull_mesh(a, freeboard_m))
    if ship_model.superstructure:
        parts.append(superstructure_mesh(a))
    return joined_mesh(parts)


def _to_cam(light: ShipLight, ship: ShipPose, camera_pose: CameraPose) -> NDArray[np.float64]:
    p = np.append(light.position_m, 1.0)
    T = camera_pose.T_cam_from_world @ (ship.T_world_from_deck if light.on_deck else np.eye(4))
    return (T @ p)[:3]


def light_splats(lights: list[ShipLight], poses: tuple[ShipPose, ...], camera_pose: CameraPose,
                 camera: CameraModel, sensor: SensorSpec, leds: LedSpec, layout: DeckLayout
                 ) -> tuple[list[Splat], NDArray[np.float64], NDArray[np.bool_]]:
    """Splats of the lights over the exposure, and their truth at mid-exposure.

    Parameters
    ----------
    lights : list of ShipLight
    poses : tuple of ShipPose
        The deck poses of the exposure (the middle one is the truth's).
    camera_pose, camera, sensor
        As for the beacons.
    leds : LedSpec
        The atmosphere (``visibility_km``).
    layout : DeckLayout
        A beacon's size and intensity, the lights' unit.

    Returns
    -------
    list of Splat
        ``beacon_id`` is ``-1 - light id``; lights behind the camera or off the image have none.
    (L, 2) array of float
        Each light's projected centre at mid-exposure, pixels (NaN behind the camera).
    (L,) array of bool
        In front of the camera and inside the image.
    """
    r = layout.beacon_radius_m
    radiance = sensor.beacon_peak * layout.intensity
    s2 = sensor.psf_sigma_px ** 2
    mid = poses[len(poses) // 2]
    uv = np.full((len(lights), 2), np.nan)
    in_image = np.zeros(len(lights), bool)
    out: list[Splat] = []
    for j, light in enumerate(lights):
        P = np.array([_to_cam(light, p, camera_pose) for p in poses])
        P_mid = _to_cam(light, mid, camera_pose)
        if P_mid[2] > 1e-6:
            uv[j] = camera.project(P_mid[None])[0]
            in_image[j] = bool(camera.in_image(uv[j][None])[0])
        if not np.all(P[:, 2] > 1e-6):
            continue
        flux = (radiance * np.pi * r * r * light.intensity * point_light_gain(P, None, camera, 0.0)
                * transmission(np.linalg.norm(P, axis=1), leds))
        centres = camera.project(P)
        comps = [(c, s2 * np.eye(2), float(f)) for c, f in zip(centres, flux)]
        sp = spot_splat(comps, light.rgb, sensor, camera, -1 - j)
        if sp is not None:
            out.append(sp)
    return out, uv, in_image


def lights_in_camera_m(lights: list[ShipLight] | tuple[ShipLight, ...], ship: ShipPose, camera_pose: CameraPose
                       ) -> NDArray[np.float64]:
    """Each light's position in the camera frame at the deck pose ``ship``, metres; (L, 3)."""
    return np.array([_to_cam(light, ship, camera_pose) for light in lights]).reshape(-1, 3)
