"""The estimator interface and registry.

An estimator is a pure function::

    fn(detections: Detections, camera: CameraModel, layout: DeckLayout,
       options: EstimateOptions) -> PoseEstimate

registered under a name with :func:`register`; the CLI (``deckpose estimate
--method NAME``) and the benchmarks find it through :func:`get`. Expected
failures (too few beacons, degenerate geometry) come back as a falsy
:class:`~deckpose.records.PoseEstimate` with a reason, never as an exception.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.records import Detections, PoseEstimate


@dataclass(frozen=True)
class EstimateOptions:
    """Options shared by all estimators.

    Attributes
    ----------
    sigma_px : float
        Pixel noise standard deviation assumed when detections carry no covariance.
    refine : bool
        Follow the estimator with a maximum-likelihood refinement, where supported.
    R_world_from_cam : (3, 3) array of float
        Known camera attitude (e.g. from the UAV's IMU); default nadir, image top to bow.
    max_reprojection_rms_px : float
        Above this reprojection RMS an estimate is flagged not ok.
    """

    sigma_px: float = 1.0
    refine: bool = False
    R_world_from_cam: np.ndarray = field(default_factory=lambda: R_WORLD_FROM_NADIR_CAM)
    max_reprojection_rms_px: float = 10.0

    def __post_init__(self) -> None:
        if not self.sigma_px > 0:
            raise ConfigError(f"sigma_px must be positive, got {self.sigma_px}")
        if not self.max_reprojection_rms_px > 0:
            raise ConfigError("max_reprojection_rms_px must be positive")


EstimatorFn = Callable[[Detections, CameraModel, DeckLayout, EstimateOptions], PoseEstimate]

_REGISTRY: dict[str, EstimatorFn] = {}

#: Modules that register the built-in estimators when imported.
_BUILTIN_MODULES: tuple[str, ...] = ("deckpose.estimate.thesis",)


def register(name: str) -> Callable[[EstimatorFn], EstimatorFn]:
    """Decorator: make ``fn`` available as estimator ``name``."""

    def deco(fn: EstimatorFn) -> EstimatorFn:
        if name in _REGISTRY and _REGISTRY[name] is not fn:
            raise ConfigError(f"an estimator named {name!r} is already registered")
        _REGISTRY[name] = fn
        return fn

    return deco


def _load_builtins() -> None:
    for mod in _BUILTIN_MODULES:
        importlib.import_module(mod)


def names() -> list[str]:
    """Names of all registered estimators."""
    _load_builtins()
    return sorted(_REGISTRY)


def get(name: str) -> EstimatorFn:
    """The estimator registered as ``name``."""
    _load_builtins()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ConfigError(f"unknown estimator {name!r}; choose one of {', '.join(sorted(_REGISTRY))}") from None
