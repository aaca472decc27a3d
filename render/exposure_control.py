"""Auto-exposure across frames: a camera's exposure controller run over each time sequence.

A real camera's auto-exposure is a controller: the exposure of frame ``k`` comes from
metering the frames before it, so it lags a sudden change of the scene (a floodlight
coming into view, the camera turning from the sea to the lit deck) and the frames after
the change over- or under-expose until it catches up. Frames here render independently,
in any order and any worker, so the controller runs before them, in a metering pre-pass:

1. each frame's scene is rasterised at ``metering_scale`` of its size and metered as
   :func:`~deckpose.render.auto_exposure.metered_exposure` meters a whole frame (the
   exposure that frame alone would take, ``m_k``; :func:`metering_exposure`);
2. per time sequence (:func:`time_sequences`: one camera, height and lighting, in time
   order) the controller (:func:`controlled_exposures`) turns the meterings into the
   exposures ``e_k``, in log exposure::

       log e_0 = log m_0                                  (settled before the sequence)
       log e_k = log e_{k-1} + clip(a_k (log m_{k-1} - log e_{k-1}), -s ln 2, s ln 2)
       a_k = 1 - exp(-(t_k - t_{k-1}) / tau)               (1 when tau = 0)

   with ``tau = time_constant_s`` and ``s = max_step_stops`` (no clip when null): a
   first-order low-pass of the meterings, one frame late; a step of the scene from
   ``m = A`` to ``m = B`` at frame ``j`` gives ``log e_k = log B + (log A - log B)
   exp(-(t_k - t_j) / tau)`` for ``k >= j``, and a constant scene ``e = m``, the exposure
   a frame metering itself takes;
3. each frame renders at its ``e_k`` (:attr:`~deckpose.render.plan.FrameSpec.exposure`),
   independently and in parallel as before; ``exposure`` and ``metered_exposure`` are
   recorded in ``frames.parquet``.

The controller draws nothing at random; it is a function of the config, so a resumed run
recomputes the same exposures.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from deckpose.render.auto_exposure import metered_exposure
from deckpose.render.lens import distort, raster_camera
from deckpose.render.plan import FrameSpec
from deckpose.render.scene import DeckRenderer, radiance_scale
from deckpose.render.scene_config import Shading
from deckpose.render.sensor_config import AutoExposureSpec, SensorSpec
from numpy.typing import ArrayLike, NDArray

from deckpose.camera import CameraModel

__all__ = ["controlled_exposures", "metering_camera", "metering_exposure", "time_sequences",
           "with_exposures"]


def controlled_exposures(metered: ArrayLike, t_s: ArrayLike, ae: AutoExposureSpec) -> NDArray[np.float64]:
    """The controller's exposures over one time sequence, from the frames' own meterings.

    Parameters
    ----------
    metered : (N,) array of float
        ``m_k``: the exposure each frame's metering asks for (unit of ``sensor.exposure``), > 0.
    t_s : (N,) array of float
        Frame times, seconds, non-decreasing.
    ae : AutoExposureSpec
        ``time_constant_s``, ``max_step_stops``, ``min_exposure``, ``max_exposure``.

    Returns
    -------
    (N,) array of float
        ``e_k`` (module docstring), within ``[min_exposure, max_exposure]``.
    """
    m = np.asarray(metered, np.float64).ravel()
    t = np.asarray(t_s, np.float64).ravel()
    if m.shape != t.shape:
        raise ValueError(f"controlled_exposures: metered {m.shape} and t_s {t.shape} must have the same shape")
    if m.size and (not np.all(np.isfinite(m)) or np.any(m <= 0)):
        raise ValueError("controlled_exposures: meterings must be finite and positive")
    if np.any(np.diff(t) < 0):
        raise ValueError("controlled_exposures: t_s must be in time order (non-decreasing)")
    log_m = np.log(m)
    out = np.empty_like(log_m)
    step_max = math.inf if ae.max_step_stops is None else ae.max_step_stops * math.log(2.0)
    for k in range(m.size):
        if k == 0:
            out[0] = log_m[0]
            continue
        dt = t[k] - t[k - 1]
        gain = 1.0 if ae.time_constant_s == 0 else -math.expm1(-dt / ae.time_constant_s)
        out[k] = out[k - 1] + min(step_max, max(-step_max, gain * (log_m[k - 1] - out[k - 1])))
    return np.clip(np.exp(out), ae.min_exposure, ae.max_exposure)


def time_sequences(plan: list[FrameSpec]) -> list[list[int]]:
    """The plan's time sequences: indices into ``plan`` per camera, height and lighting, in time order.

    A heights grid replays the motion once per camera, height and lighting; an approach
    flies once per camera and lighting (its frames share the nominal ``height_m``).
    """
    groups: dict[tuple[str, float, str], list[int]] = {}
    for i, spec in enumerate(plan):
        groups.setdefault((spec.camera_name, spec.height_m, spec.lighting.value), []).append(i)
    return [sorted(idx, key=lambda i: (plan[i].t_s, plan[i].frame_id)) for idx in groups.values()]


def metering_camera(camera: CameraModel, scale: float) -> CameraModel:
    """The camera the pre-pass meters with: the same view at ``scale`` of the size (at least 16 px a side)."""
    if scale >= 1.0:
        return camera
    w = max(16, round(camera.width_px * scale))
    h = max(16, round(camera.height_px * scale))
    return camera.with_size(w, h)


def metering_exposure(spec: FrameSpec, camera: CameraModel, renderer: DeckRenderer, sensor: SensorSpec,
                      shading: Shading, ae: AutoExposureSpec) -> float:
    """The exposure a frame's own metering asks for, from its scene at ``ae.metering_scale``.

    The scene is the frame's raster as :func:`~deckpose.render.frame.render_frame` draws it
    (deck and sea at the frame's camera pose and time, through the lens), at the metering
    camera's size (:func:`metering_camera`); at scale 1 this is the metering a frame
    takes of itself. A rolling shutter's UAV motion within the frame is left out (the
    metering sees the frame-time view).
    """
    cam = metering_camera(camera, ae.metering_scale)
    raster = renderer.render(raster_camera(cam), spec.camera_pose, spec.ship, spec.t_s, spec.lighting)
    raster = distort(raster, cam)
    return metered_exposure(raster, radiance_scale(spec.lighting, shading), sensor, ae)


def with_exposures(plan: list[FrameSpec], metered: ArrayLike, ae: AutoExposureSpec) -> list[FrameSpec]:
    """The plan with each frame's controlled exposure and its own metering set.

    Parameters
    ----------
    plan : list of FrameSpec
    metered : (len(plan),) array of float
        Each frame's own metering (:func:`metering_exposure`), in plan order.
    ae : AutoExposureSpec
    """
    m = np.asarray(metered, np.float64).ravel()
    if m.size != len(plan):
        raise ValueError(f"with_exposures: {m.size} meterings for {len(plan)} frames")
    exposure = np.empty(len(plan))
    for idx in time_sequences(plan):
        exposure[idx] = controlled_exposures(m[idx], [plan[i].t_s for i in idx], ae)
    return [dataclasses.replace(s, exposure=float(e), metered_exposure=float(mk))
            for s, e, mk in zip(plan, exposure, m)]
