"""Run a registered estimator on one frame or many, applying ``--refine`` to any of them.

This is the entry point the CLI and the benchmarks use: estimators that refine
by themselves (``conic``, ``pnp``) mark their result ``extras["refined"] = 1``;
for any other (the thesis's) :func:`run_estimator` appends the generic
maximum-likelihood refinement when ``options.refine`` is set.
"""

from __future__ import annotations

from collections.abc import Iterable

from deckpose.estimate import registry
from deckpose.estimate.refine import refine_estimate
from deckpose.estimate.registry import EstimateOptions

from deckpose.camera import CameraModel
from deckpose.layout import DeckLayout
from deckpose.records import Detections, PoseEstimate


def run_estimator(
    name: str, detections: Detections, camera: CameraModel, layout: DeckLayout, options: EstimateOptions
) -> PoseEstimate:
    """Estimate one frame with estimator ``name`` (refined when ``options.refine``)."""
    fn = registry.get(name)
    est = fn(detections, camera, layout, options)
    if options.refine and est.ok and not est.extras.get("refined", 0.0):
        est = refine_estimate(est, detections, camera, layout, options)
    return est


def estimate_many(
    name: str,
    detections: Iterable[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
) -> list[PoseEstimate]:
    """Estimate every frame of ``detections`` with estimator ``name``.

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
    return [run_estimator(name, det, camera, layout, options) for det in detections]
