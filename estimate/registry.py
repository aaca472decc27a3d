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

import functools
import importlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from deckpose.camera import CameraModel
from deckpose.errors import ConfigError
from deckpose.layout import DeckLayout
from deckpose.pose import R_WORLD_FROM_NADIR_CAM
from deckpose.records import Detections, PoseEstimate

#: Accepted pixel noise, px: beyond it the squared sigma and its inverse leave float64's safe range.
SIGMA_PX_RANGE = (1e-6, 1e6)


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
    use_detection_covariance : bool
        Weight by the detections' own covariances (when they are not all the
        identity, the "unknown" default); otherwise by ``sigma_px``.
    outlier_chi2 : float
        A point whose squared Mahalanobis reprojection residual exceeds this is an
        outlier (spurious point or wrong id): it is removed and the pose re-estimated.
    max_outliers : int
        At most this many points are removed; more outliers make the estimate not ok.
    ambiguity_chi2 : float
        The planar two-fold ambiguity counts as unresolved when the second solution's
        chi-square exceeds the best one's by less than this while the two poses differ
        by more than 3 sigma.
    assume_level_deck : bool
        When the two-fold ambiguity is unresolved, pick the solution whose deck is
        closer to level (stated in the result's extras) instead of failing.
    conic_polish_steps : int
        Gauss-Newton steps on all identified beacons that polish the ``conic``
        method's closed-form solution (0 = the pure geometric solution, within about
        1.6x the Cramér–Rao bound with all beacons; the default single step brings it
        to the bound and makes the reported covariance, which assumes an efficient
        estimate, trustworthy with few beacons too). ``refine`` iterates to
        convergence instead.
    posterior_mean : bool
        Report the posterior mean of the pose under a uniform prior instead of the
        maximum-likelihood pose (:mod:`~estimate.posterior_mean`): a lower RMS error
        where the noise is large against the beacon ring's size in the image, the same
        pose where it is small; biased, deterministic. Implies ``refine``.
    """

    sigma_px: float = 1.0
    refine: bool = False
    R_world_from_cam: np.ndarray = field(default_factory=lambda: R_WORLD_FROM_NADIR_CAM)
    max_reprojection_rms_px: float = 10.0
    use_detection_covariance: bool = True
    outlier_chi2: float = 30.0
    max_outliers: int = 3
    ambiguity_chi2: float = 4.0
    assume_level_deck: bool = False
    conic_polish_steps: int = 1
    posterior_mean: bool = False

    def __post_init__(self) -> None:
        if self.posterior_mean and not self.refine:
            object.__setattr__(self, "refine", True)  # the posterior is sampled around the ML fit
        if not SIGMA_PX_RANGE[0] <= self.sigma_px <= SIGMA_PX_RANGE[1]:
            raise ConfigError(f"sigma_px must be a pixel noise between {SIGMA_PX_RANGE[0]:g} and "
                              f"{SIGMA_PX_RANGE[1]:g} px, got {self.sigma_px}")
        if not self.max_reprojection_rms_px > 0:
            raise ConfigError("max_reprojection_rms_px must be positive")
        R = np.array(self.R_world_from_cam, dtype=float)
        if R.shape != (3, 3) or not np.isfinite(R).all():
            raise ConfigError(f"R_world_from_cam must be a finite 3x3 matrix, got shape {R.shape}")
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise ConfigError("R_world_from_cam must be a proper rotation matrix (orthonormal, det +1)")
        R.setflags(write=False)
        object.__setattr__(self, "R_world_from_cam", R)
        if not self.outlier_chi2 > 0:
            raise ConfigError(f"outlier_chi2 must be positive, got {self.outlier_chi2}")
        if int(self.max_outliers) < 0:
            raise ConfigError(f"max_outliers must be >= 0, got {self.max_outliers}")
        if int(self.conic_polish_steps) < 0:
            raise ConfigError(f"conic_polish_steps must be >= 0, got {self.conic_polish_steps}")
        if not self.ambiguity_chi2 >= 0:
            raise ConfigError(f"ambiguity_chi2 must be >= 0, got {self.ambiguity_chi2}")


EstimatorFn = Callable[[Detections, CameraModel, DeckLayout, EstimateOptions], PoseEstimate]

_REGISTRY: dict[str, EstimatorFn] = {}

#: Modules that register the built-in estimators when imported.
_BUILTIN_MODULES: tuple[str, ...] = (
    "deckpose.estimate.thesis",
    "deckpose.estimate.conic",
    "deckpose.estimate.pnp",
)


def register(name: str) -> Callable[[EstimatorFn], EstimatorFn]:
    """Decorator: make ``fn`` available as estimator ``name``."""

    def deco(fn: EstimatorFn) -> EstimatorFn:
        if name in _REGISTRY and _REGISTRY[name] is not fn:
            raise ConfigError(f"an estimator named {name!r} is already registered")
        _REGISTRY[name] = fn
        return fn

    return deco


@functools.cache
def _load_builtins() -> None:
    """Import the built-in estimators' modules, once (a lone frame pays for every look-up)."""
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
        several = (" (one method per call: run once for each; `deckpose pipeline --method a,b` and "
                   "`estimator-tables` take a list)") if "," in name else ""
        raise ConfigError(
            f"unknown estimator {name!r}{several}; choose one of {', '.join(sorted(_REGISTRY))}") from None


#: Suffixes of a method label and the option each sets: ``conic+refine``, ``pnp+mean``.
VARIANT_SUFFIXES: dict[str, str] = {"refine": "refine", "mean": "posterior_mean"}


@dataclass(frozen=True)
class MethodSpec:
    """An estimator with the options its label names (``pnp+mean`` = pnp, posterior mean).

    Attributes
    ----------
    name : str
        A registered estimator.
    refine : bool
    posterior_mean : bool
    """

    name: str
    refine: bool = False
    posterior_mean: bool = False

    @property
    def label(self) -> str:
        """``name``, ``name+refine`` or ``name+mean``: how runs and reports name this variant."""
        if self.posterior_mean:
            return f"{self.name}+mean"
        return f"{self.name}+refine" if self.refine else self.name


def parse_method(label: str) -> MethodSpec:
    """``thesis``, ``conic+refine``, ``pnp+mean`` ... as a :class:`MethodSpec`.

    Raises
    ------
    ConfigError
        For an unknown estimator or suffix, with the valid choices.
    """
    name, *suffixes = str(label).split("+")
    get(name)  # unknown estimator: ConfigError with the names
    flags = {"refine": False, "posterior_mean": False}
    for s in suffixes:
        if s not in VARIANT_SUFFIXES:
            raise ConfigError(f"unknown variant '+{s}' in method {label!r}; a method is an estimator "
                              f"({', '.join(names())}) optionally followed by "
                              f"{' or '.join('+' + k for k in VARIANT_SUFFIXES)}")
        flags[VARIANT_SUFFIXES[s]] = True
    return MethodSpec(name, **flags)
