"""One frame through a detector and identification: the detection stage's unit of work."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from deckpose.detect import registry
from deckpose.detect.colour import blob_rgb_flux
from deckpose.detect.guided_look import look_again
from deckpose.detect.identify import IdentifyOptions, identify_beacons
from deckpose.detect.registry import Blobs, DetectorOptions
from numpy.typing import NDArray

from deckpose.layout import DeckLayout
from deckpose.records import UNASSIGNED, Detections, Frame

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FrameDetections:
    """Detections of one frame with the detector's extra measurements and the outcome.

    Attributes
    ----------
    detections : Detections
        Centres, ids, covariances and scores (the record the estimators read).
    flux_dn : (N,) array of float
        Background-subtracted flux per detection, DN.
    size_px : (N,) array of float
        Gaussian-equivalent spot sigma per detection, pixels.
    detector : str
    ok : bool
        Detection and identification both succeeded.
    reason : str
        Why not (empty when ok). Detections may be present when only
        identification failed.
    seconds : float
        Wall time of detection plus identification.
    cpu_seconds : float
        CPU time of this thread for the same work (on a shared machine, the
        one-core cost: wall time also counts time other processes held the core).
    """

    detections: Detections
    flux_dn: FloatArray
    size_px: FloatArray
    detector: str
    ok: bool
    reason: str
    seconds: float
    cpu_seconds: float = math.nan

    def __bool__(self) -> bool:
        return self.ok

    @classmethod
    def failed(
        cls,
        frame_id: int,
        detector: str,
        reason: str,
        seconds: float = 0.0,
        cpu_seconds: float = math.nan,
    ) -> FrameDetections:
        empty = Detections(np.zeros((0, 2)), np.zeros(0, np.int64), frame_id=frame_id)
        return cls(empty, np.zeros(0), np.zeros(0), detector, False, reason, seconds, cpu_seconds)


def detect_frame(
    frame: Frame,
    detector: str,
    layout: DeckLayout,
    *,
    options: DetectorOptions = DetectorOptions(),
    identify_options: IdentifyOptions = IdentifyOptions(),
    identify: bool = True,
) -> FrameDetections:
    """Run detector ``detector`` on ``frame`` and identify the beacons.

    A detector with a candidate kernel (:func:`~deckpose.detect.registry.register_kernel`:
    ``cog``, ``gauss``) gets a second look on a colour frame whose ring was fitted: the
    empty ring slots and a missing centre are searched again in the beacon's colour
    (:func:`~deckpose.detect.guided_look.look_again`), and identification runs again with
    what it adds; the frame keeps the result only if it is identified, or was not before.

    Parameters
    ----------
    frame : Frame
    detector : str
        A name from :func:`deckpose.detect.registry.names`.
    layout : DeckLayout
    options : DetectorOptions
    identify_options : IdentifyOptions
    identify : bool
        Skip identification (all ids unassigned) when False.

    Returns
    -------
    FrameDetections
        Never raises for a bad frame: failures come back with a reason.
    """
    fn = registry.get(detector)
    t0, c0 = time.perf_counter(), time.thread_time()
    try:
        blobs: Blobs = fn(frame, options)
    except Exception as exc:  # noqa: BLE001 - a detector bug must not end a batch: the frame fails
        return FrameDetections.failed(
            frame.frame_id,
            detector,
            f"detector {detector!r} raised {type(exc).__name__}: {exc}",
            time.perf_counter() - t0,
            time.thread_time() - c0,
        )
    if not blobs:
        return FrameDetections.failed(
            frame.frame_id,
            detector,
            blobs.reason,
            time.perf_counter() - t0,
            time.thread_time() - c0,
        )
    n = len(blobs)
    ids = np.full(n, UNASSIGNED, np.int64)
    reason = ""
    if identify:
        rgb = None
        if frame.image.ndim == 3:
            radii = np.maximum(2.0, 2.0 * blobs.size_px)
            rgb = blob_rgb_flux(frame.image, blobs.points_px, radii)
        try:
            ident = identify_beacons(
                blobs.points_px, layout, frame.camera, rgb_flux=rgb, options=identify_options
            )
            note = blobs.note
            kernel = registry.kernel(detector)
            if rgb is not None and kernel is not None and ident.ring_homography is not None:
                # the empty ring slots searched again, in the beacon's colour (guided_look)
                look = look_again(frame.image, frame.camera, blobs, ident, rgb, layout, kernel,
                                  options, identify_options)
                note = "; ".join(x for x in (note, look.note) if x)
                if look.rows:
                    more = blobs.joined(look.rows)
                    rgb_more = blob_rgb_flux(frame.image, more.points_px,
                                             np.maximum(2.0, 2.0 * more.size_px))
                    again = identify_beacons(more.points_px, layout, frame.camera,
                                             rgb_flux=rgb_more, options=identify_options)
                    if again.ok or not ident.ok:
                        blobs, ident = more, again
                        n = len(blobs)
            ids = np.asarray(ident.beacon_ids)
            reason = "" if ident else f"identification: {ident.reason}"
            if reason and note:
                reason += f" ({note})"
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            # degenerate geometry the identification did not foresee: the frame fails
            ids = np.full(n, UNASSIGNED, np.int64)
            reason = f"identification raised {type(exc).__name__}: {exc}"
    seconds, cpu_seconds = time.perf_counter() - t0, time.thread_time() - c0
    dets = Detections(
        blobs.points_px, ids, blobs.covariance_px2, blobs.score, frame_id=frame.frame_id
    )
    return FrameDetections(
        dets,
        blobs.flux_dn,
        blobs.size_px,
        detector,
        not reason,
        reason,
        float(seconds),
        float(cpu_seconds),
    )
