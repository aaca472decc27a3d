"""Run a registered estimator on one frame or many, applying ``--refine`` to any of them.

This is the entry point the CLI and the benchmarks use: estimators that refine
by themselves (``conic``, ``pnp``) mark their result ``extras["refined"] = 1``;
for any other (the thesis's) :func:`run_estimator` appends the generic
maximum-likelihood refinement when ``options.refine`` is set, and
``options.posterior_mean`` then replaces the refined pose by its posterior mean.

:func:`estimate_batch` estimates many frames at once: ``conic``, ``pnp`` and
``thesis`` (and the refinement) run as stacked array operations over all frames
that share a beacon set, which costs a small fraction of one call per frame.
``thesis``, ``conic``, ``pnp`` and the refinement have one implementation each (a
lone frame is a batch of one of :func:`~deckpose.estimate.thesis.estimate_thesis_frames`,
:func:`~deckpose.estimate.conic.estimate_conic_frames`,
:func:`~deckpose.estimate.pnp.estimate_pnp_frames` and
:func:`~deckpose.estimate.refine.refine_estimates`), so every result is the one
:func:`run_estimator` gives.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable

import numpy as np
from deckpose.estimate import registry
from deckpose.estimate.conic import estimate_conic_frames
from deckpose.estimate.pnp import estimate_pnp_frames
from deckpose.estimate.pose_checks import check_poses
from deckpose.estimate.posterior_mean import apply_posterior_mean
from deckpose.estimate.refine import refine_estimate, refine_estimates
from deckpose.estimate.registry import EstimateOptions
from deckpose.estimate.thesis import estimate_thesis_frames
from deckpose.estimate.thesis_assumptions import flag_off_centre
from numpy.typing import NDArray

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError, ShapeError
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate

#: Frames estimated together in one stacked call (bounds memory, keeps arrays in cache).
CHUNK_FRAMES = 2048


def chunk_slices(n_frames: int) -> list[slice]:
    """The batches :func:`estimate_batch` makes of ``n_frames`` frames: :data:`CHUNK_FRAMES` each, then the rest."""
    return [slice(lo, lo + CHUNK_FRAMES) for lo in range(0, n_frames, CHUNK_FRAMES)]


def run_estimator(
    name: str, detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate one frame with estimator ``name`` (refined when ``options.refine``)."""
    fn = registry.get(name)
    est = fn(detections, camera, layout, options)
    if _checks_centring(name, options) and est.ok:
        ref = run_estimator("pnp", detections, camera, layout, options)
        est = flag_off_centre([est], [detections], [ref], camera, layout, options)[0]
    if options.refine and est.ok and not est.extras.get("refined", 0.0):
        est = refine_estimate(est, detections, camera, layout, options)
    if options.posterior_mean:
        est = apply_posterior_mean([est], [detections], camera, layout, options,
                                   np.asarray(options.R_world_from_cam)[None])[0]
    return check_poses([est])[0].for_frame(detections.frame_id)


def _checks_centring(name: str, options: EstimateOptions) -> bool:
    """Whether ``name``'s results get the off-centre check (:mod:`~.thesis_assumptions`).

    The faithful ``thesis`` method assumes the deck centre on the optical axis; its
    refinement (and posterior mean) fits surge and sway, so those need no check.
    """
    return name == "thesis" and not options.refine and not options.posterior_mean


def _check_rotations(R: np.ndarray) -> None:
    """The per-frame form of :class:`EstimateOptions`' check of ``R_world_from_cam``."""
    with np.errstate(invalid="ignore"):
        bad = ~np.isfinite(R).all(axis=(1, 2))
        bad |= ~np.isclose(R.swapaxes(1, 2) @ R, np.eye(3), atol=1e-6).all(axis=(1, 2))
        bad |= np.linalg.det(np.where(np.isfinite(R), R, 0.0)) < 0
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ConfigError(f"R_world_from_cam of frame {i} (position in the batch) is not a proper rotation "
                          "matrix (finite, orthonormal, det +1); fix the camera attitudes")


def _frame_options(options: EstimateOptions, R: np.ndarray) -> EstimateOptions:
    if np.array_equal(R, options.R_world_from_cam):
        return options
    return dataclasses.replace(options, R_world_from_cam=R)


def estimate_batch(
    name: str,
    detections: Iterable[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    *,
    R_world_from_cam: NDArray[np.float64] | None = None,
    progress: Callable[[int], object] | None = None,
) -> list[PoseEstimate]:
    """Estimate many frames of one camera with estimator ``name``, batched where possible.

    Parameters
    ----------
    name : str
        A registered estimator. ``conic``, ``pnp`` and ``thesis`` (and
        ``options.refine`` for any estimator) are batched; others run frame by frame.
    detections : iterable of Detections
    camera : CameraModel
    layout : DeckLayout
    options : EstimateOptions
    R_world_from_cam : (F, 3, 3) array of float, optional, keyword-only
        Each frame's camera attitude, instead of ``options.R_world_from_cam``.
    progress : callable, optional, keyword-only
        Called with the number of frames done after each chunk of :data:`CHUNK_FRAMES`.

    Returns
    -------
    list of PoseEstimate
        One per frame, in order, each with its detections' ``frame_id``: the same records
        as :func:`run_estimator` frame by frame, to rounding (the iterations stop on the
        same tolerances).
    """
    fn = registry.get(name)
    dets = list(detections)
    F = len(dets)
    if R_world_from_cam is None:
        R_opt = np.asarray(options.R_world_from_cam, dtype=float)
        R_wc = R_opt[None] if F == 1 else np.broadcast_to(R_opt, (F, 3, 3))
    else:
        R_wc = np.asarray(R_world_from_cam, dtype=float)
        if R_wc.shape != (F, 3, 3):
            raise ShapeError(f"R_world_from_cam: expected ({F}, 3, 3) for {F} frames, got {R_wc.shape}; "
                             "give one camera attitude per frame")
        _check_rotations(R_wc)
    out: list[PoseEstimate] = []
    for part in chunk_slices(F):
        chunk, R_chunk = dets[part], np.ascontiguousarray(R_wc[part])
        ests: list[PoseEstimate]
        if name == "conic":
            ests = estimate_conic_frames(chunk, camera, layout, options, R_chunk)
        elif name == "pnp":
            ests = estimate_pnp_frames(chunk, camera, layout, options, R_chunk)
        elif name == "thesis":
            ests = estimate_thesis_frames(chunk, camera, layout, R_chunk)
        else:
            ests = [fn(d, camera, layout, _frame_options(options, R)) for d, R in zip(chunk, R_chunk)]
        if _checks_centring(name, options):
            fresh = [i for i in range(len(ests)) if ests[i].ok]
            if fresh:
                refs = estimate_batch("pnp", [chunk[i] for i in fresh], camera, layout, options,
                                      R_world_from_cam=R_chunk[fresh])
                flagged = flag_off_centre([ests[i] for i in fresh], [chunk[i] for i in fresh],
                                          refs, camera, layout, options)
                for i, e in zip(fresh, flagged):
                    ests[i] = e
        if options.refine and name not in ("conic", "pnp"):
            ests = refine_estimates(ests, chunk, camera, layout, options, R_chunk)
        if options.posterior_mean:
            ests = apply_posterior_mean(ests, chunk, camera, layout, options, R_chunk)
        out.extend(e.for_frame(d.frame_id) for e, d in zip(check_poses(ests), chunk, strict=True))
        if progress is not None:
            progress(len(chunk))
    return out


def estimate_many(
    name: str,
    detections: Iterable[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
) -> list[PoseEstimate]:
    """Estimate every frame of ``detections`` with estimator ``name`` (batched: :func:`estimate_batch`).

    Parameters
    ----------
    name : str
        A registered estimator (:func:`deckpose.estimate.registry.names`).
    detections : iterable of Detections
    camera : CameraModel
    layout : DeckLayout
    options : EstimateOptions

    Returns
    -------
    list of PoseEstimate
        One per frame, in order; failures are falsy estimates with a reason.
    """
    return estimate_batch(name, detections, camera, layout, options)
