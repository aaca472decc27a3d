"""The detector interface, its measurement record and the registry.

A detector is a pure function::

    fn(frame: Frame, options: DetectorOptions) -> Blobs

registered under a name with :func:`register`; ``deckpose detect --detector NAME``
and ``deckpose bench-detectors`` find it through :func:`get`. Most detectors only
measure one blob in a full-resolution window around each candidate that the shared
coarse-to-fine search finds; :func:`deckpose.detect.candidates.measure_candidates`
does the rest, so a new detector is a few lines::

    from deckpose.detect import registry
    from deckpose.detect.candidates import measure_candidates

    @registry.register("peak")
    def peak(frame, options):
        def measure(c):              # c: a candidate.Candidate (full-resolution window)
            s = c.signal()           # background-subtracted pixels
            v, u = np.unravel_index(np.argmax(s), s.shape)
            return c.blob(u + c.u0, v + c.v0, flux_dn=float(s.max()))
        return measure_candidates(frame, options, measure)

Modules outside deckpose can register detectors too: ``deckpose detect --plugin
MODULE`` imports ``MODULE`` first, and installed packages can declare an entry
point in the group ``deckpose.detectors``.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError, check_shape
from deckpose.records import Frame

if TYPE_CHECKING:
    from deckpose.detect.candidate import Candidate

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DetectorOptions:
    """Options shared by all detectors.

    Attributes
    ----------
    threshold_sigma : float
        Detection threshold, in standard deviations of the frame's background
        noise above its background level (both measured per frame).
    coarse_max_px : int
        The candidate search runs on a block-averaged copy of the frame with at
        most this many pixels (coarse-to-fine search on large frames).
    min_area_px : int
        Smallest blob (full-resolution pixels above threshold) kept.
    max_blobs : int
        Most candidates a frame may give. Beyond it the bright-spot and threshold
        searches fail the frame (noise, glare); the significance search keeps the
        ``max_blobs`` most significant spots and lets identification decide (point
        defects, :mod:`deckpose.detect.defects`, are dropped before the count).
    window_sigma : float
        Radius of the measuring window, in spot standard deviations (cog, log).
    gain_dn_per_e : float or None
        Sensor gain, DN per electron, for the noise model behind covariances and
        fit weights; ``None`` estimates it from the frame's blobs.
    background_kernel_px : int
        0: one background level for the whole frame (dark sea or sky). Otherwise
        the candidate search first removes an uneven background (a lit deck) by a
        grey opening with a disc of this diameter, full-resolution pixels; it
        must exceed the largest beacon's diameter. With ``spot_level`` > 0 the
        bright-spot search runs on the frame minus its opening (a white top-hat,
        :func:`deckpose.detect.spots.tophat_spot_search`) and the windows are
        measured there; with ``spot_level`` = 0 every blob ``threshold_sigma``
        local noise sigmas above the opened, block-averaged frame is a candidate.
    spot_level : float
        Bright-spot search (:mod:`deckpose.detect.spots`): candidates are pixels whose
        largest channel lies this fraction of the way from the frame's background to
        its bright-spot level (beacon cores), so deck markings, texture and the lit
        sea are not candidates. 0 switches it off: every blob ``threshold_sigma``
        noise sigmas above the background is a candidate (dark frames of
        unsaturated spots of very different brightness).
    significance_sigma : float
        Significance search (:mod:`deckpose.detect.significance`), on with the
        bright-spot search: every compact spot this many local noise sigmas above the
        highest point of a ring around it is a candidate too, however dim beside the
        brightest beacon. 0 switches it off (only the bright-spot search).
    """

    threshold_sigma: float = 6.0
    coarse_max_px: int = 1_000_000
    min_area_px: int = 2
    max_blobs: int = 200
    window_sigma: float = 3.0
    gain_dn_per_e: float | None = None
    background_kernel_px: int = 0
    spot_level: float = 0.8
    significance_sigma: float = 5.0

    def __post_init__(self) -> None:
        if not self.threshold_sigma > 0:
            raise ConfigError(f"threshold_sigma (--threshold-sigma) must be positive, got {self.threshold_sigma}")
        if self.coarse_max_px < 10_000:
            raise ConfigError(f"coarse_max_px must be >= 10000, got {self.coarse_max_px}")
        if self.min_area_px < 1 or self.max_blobs < 1:
            raise ConfigError("min_area_px and max_blobs must be >= 1")
        if not self.window_sigma >= 1.0:
            raise ConfigError(f"window_sigma must be >= 1, got {self.window_sigma}")
        if self.background_kernel_px < 0:
            raise ConfigError(f"background_kernel_px (--background-kernel-px) must be >= 0, got {self.background_kernel_px}")
        if not 0.0 <= self.spot_level < 1.0:
            raise ConfigError(f"spot_level (--spot-level) must be in [0, 1), got {self.spot_level}")
        if not (self.significance_sigma == 0 or self.significance_sigma >= 2.0):
            raise ConfigError(
                f"significance_sigma (--significance-sigma) must be 0 (off) or >= 2, got {self.significance_sigma}"
            )
        if self.gain_dn_per_e is not None and not self.gain_dn_per_e > 0:
            raise ConfigError(f"gain_dn_per_e (--gain) must be positive or None, got {self.gain_dn_per_e}")


def _ro(a: object, dtype: type = float) -> np.ndarray:
    arr = np.array(a, dtype=dtype)
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class Blobs:
    """What a detector measures in one frame, before identification.

    A frame the detector could not handle is a falsy ``Blobs`` with a ``reason``.

    Attributes
    ----------
    points_px : (N, 2) array of float
        Blob centres ``(u, v)``, distorted pixels as in the image.
    covariance_px2 : (N, 2, 2) array of float
        Covariance of each centre, px^2.
    flux_dn : (N,) array of float
        Background-subtracted summed intensity, DN.
    size_px : (N,) array of float
        Gaussian-equivalent standard deviation of the spot, pixels.
    score : (N,) array of float
        Signal-to-noise ratio of the blob (larger = better).
    ok : bool
    reason : str
        Why the frame failed (empty when ok).
    note : str
        What the search left out on an ok frame (e.g. spots beyond ``max_blobs``), so
        that a later failure (identification) can say it; empty when nothing.
    gain_dn_per_e : float
        The gain the covariances were computed with, DN per electron (given or
        estimated from the frame's candidates); NaN when the detector does not say.
    """

    points_px: FloatArray
    covariance_px2: FloatArray
    flux_dn: FloatArray
    size_px: FloatArray
    score: FloatArray
    ok: bool = True
    reason: str = ""
    note: str = ""
    gain_dn_per_e: float = math.nan

    def __post_init__(self) -> None:
        pts = _ro(self.points_px).reshape(-1, 2)
        n = pts.shape[0]
        cov = _ro(self.covariance_px2).reshape(-1, 2, 2)
        check_shape("covariance_px2", cov, (n, 2, 2))
        object.__setattr__(self, "points_px", pts)
        object.__setattr__(self, "covariance_px2", cov)
        for name in ("flux_dn", "size_px", "score"):
            arr = _ro(getattr(self, name)).reshape(-1)
            check_shape(name, arr, (n,))
            object.__setattr__(self, name, arr)
        if self.ok == bool(self.reason):
            raise ValueError("Blobs: ok must be True with no reason, or False with a reason")

    def __len__(self) -> int:
        return int(self.points_px.shape[0])

    def __bool__(self) -> bool:
        return self.ok

    @classmethod
    def empty(cls, reason: str = "") -> Blobs:
        """No blobs; failed when ``reason`` is given."""
        z = np.zeros(0)
        return cls(np.zeros((0, 2)), np.zeros((0, 2, 2)), z, z, z, ok=not reason, reason=reason)

    @classmethod
    def stack(cls, rows: list[tuple[float, float, FloatArray, float, float, float]], *,
              note: str = "", gain_dn_per_e: float = math.nan) -> Blobs:
        """Build from ``(u, v, cov (2, 2), flux_dn, size_px, score)`` tuples."""
        if not rows:
            return cls.empty()
        u, v, cov, flux, size, score = zip(*rows)
        return cls(np.column_stack([u, v]), np.stack(cov), np.asarray(flux, float),
                   np.asarray(size, float), np.asarray(score, float), note=note,
                   gain_dn_per_e=gain_dn_per_e)

    def joined(self, rows: list[tuple[float, float, FloatArray, float, float, float]]) -> Blobs:
        """These blobs with ``rows`` appended (same note and gain); ``self`` when none."""
        if not rows:
            return self
        u, v, cov, flux, size, score = zip(*rows)
        return Blobs(np.vstack([self.points_px, np.column_stack([u, v])]),
                     np.concatenate([self.covariance_px2, np.stack(cov)]),
                     np.concatenate([self.flux_dn, np.asarray(flux, float)]),
                     np.concatenate([self.size_px, np.asarray(size, float)]),
                     np.concatenate([self.score, np.asarray(score, float)]),
                     note=self.note, gain_dn_per_e=self.gain_dn_per_e)


DetectorFn = Callable[[Frame, DetectorOptions], Blobs]

#: One row of :class:`Blobs`: ``(u, v, cov (2, 2), flux_dn, size_px, score)``.
BlobRow = tuple[float, float, FloatArray, float, float, float]
#: A detector's measurement of given candidates (one row or ``None`` per candidate), the
#: kernel its frame function maps over the search's candidates; the guided second look
#: (:mod:`~deckpose.detect.guided_look`) measures its spots with it.
KernelFn = Callable[["list[Candidate]", DetectorOptions], "list[BlobRow | None]"]

_REGISTRY: dict[str, DetectorFn] = {}
_KERNELS: dict[str, KernelFn] = {}

#: Modules that register the built-in detectors when imported.
_BUILTIN_MODULES: tuple[str, ...] = (
    "deckpose.detect.binary",
    "deckpose.detect.cog",
    "deckpose.detect.gauss",
    "deckpose.detect.log_blobs",
    "deckpose.detect.opencv_blob",
    "deckpose.detect.peers",
)

#: Peer detectors of the optional extra ``peers``, and the package each needs.
OPTIONAL_DETECTORS = {"sep": "sep", "photutils": "photutils"}

_loaded = False


def register(name: str) -> Callable[[DetectorFn], DetectorFn]:
    """Decorator: make ``fn`` available as detector ``name``."""

    def deco(fn: DetectorFn) -> DetectorFn:
        if name in _REGISTRY and _REGISTRY[name] is not fn:
            raise ConfigError(f"a detector named {name!r} is already registered")
        _REGISTRY[name] = fn
        if _LOADING:
            _PLUGIN_OF[name] = _LOADING[-1]
        return fn

    return deco


def register_kernel(name: str, kernel: KernelFn) -> None:
    """Say that detector ``name`` measures each candidate with ``kernel``.

    Optional: a detector with a kernel gets the guided second look
    (:mod:`~deckpose.detect.guided_look`) in :func:`~deckpose.detect.frame_detection.detect_frame`.
    """
    _KERNELS[name] = kernel


def kernel(name: str) -> KernelFn | None:
    """The candidate kernel of detector ``name`` (:func:`register_kernel`), or ``None``."""
    _load_builtins()
    return _KERNELS.get(name)


def unregister(name: str) -> None:
    """Remove detector ``name`` (for tests and interactive sessions)."""
    _REGISTRY.pop(name, None)
    _KERNELS.pop(name, None)
    _PLUGIN_OF.pop(name, None)


def _load_builtins() -> None:
    global _loaded
    if _loaded:
        return
    _loaded = True
    for mod in _BUILTIN_MODULES:
        importlib.import_module(mod)
    from importlib.metadata import entry_points

    for ep in entry_points(group="deckpose.detectors"):
        ep.load()


#: The plugin (module name or absolute file path) that registered each detector it registered.
_PLUGIN_OF: dict[str, str] = {}
#: The plugins being imported by :func:`load_plugin` now (innermost last).
_LOADING: list[str] = []


def plugins_for(detectors: Iterable[str]) -> tuple[str, ...]:
    """The plugins that registered ``detectors``, for a worker process to import (no duplicates).

    A module name or an absolute file path each, as :func:`load_plugin` takes it.

    Raises
    ------
    ConfigError
        A detector registered by a script's own ``__main__`` (no other process can import it).
    """
    out: list[str] = []
    for d in detectors:
        p = _PLUGIN_OF.get(d)
        if p is None:
            module = getattr(get(d), "__module__", "") or ""
            if module == "__main__":
                raise ConfigError(f"detector {d!r} is registered by the running script itself, which "
                                  "worker processes cannot import; move it into a module or use workers=1")
            if module.startswith("deckpose.") or module in _BUILTIN_MODULES:
                continue
            p = module  # registered on import of an installed module: the workers import it too
        if p not in out:
            out.append(p)
    return tuple(out)


def load_plugin(module: str) -> None:
    """Import a user module that registers detectors with :func:`register`.

    ``module`` is a module name (found on ``sys.path`` or in the current folder)
    or the path of a Python file (``./mypeak.py``). File paths are kept absolute, so
    a worker process started in another folder finds the same file.
    """
    import sys
    from pathlib import Path

    path = Path(module)
    try:
        if module.endswith(".py") or path.is_file():
            if not path.is_file():
                raise ConfigError(f"cannot import detector plugin {module!r}: no such file")
            spec = importlib.util.spec_from_file_location(path.stem, path)
            if spec is None or spec.loader is None:
                raise ConfigError(f"cannot import detector plugin {module!r}: not a Python file")
            mod = importlib.util.module_from_spec(spec)
            sys.modules[path.stem] = mod
            _LOADING.append(str(path.resolve()))
            try:
                spec.loader.exec_module(mod)
            except BaseException:
                sys.modules.pop(path.stem, None)  # no half-imported module stays behind
                raise
            finally:
                _LOADING.pop()
            return
        if "" not in sys.path and str(Path.cwd()) not in sys.path:
            sys.path.insert(0, str(Path.cwd()))  # a module in the current folder
        _LOADING.append(module)
        try:
            importlib.import_module(module)
        finally:
            _LOADING.pop()
    except ConfigError:
        raise
    except Exception as exc:
        raise ConfigError(
            f"cannot import detector plugin {module!r}: {type(exc).__name__}: {exc}"
        ) from exc


def names() -> list[str]:
    """Names of all registered detectors."""
    _load_builtins()
    return sorted(_REGISTRY)


def get(name: str) -> DetectorFn:
    """The detector registered as ``name``."""
    _load_builtins()
    try:
        return _REGISTRY[name]
    except KeyError:
        if name in OPTIONAL_DETECTORS:
            raise ConfigError(
                f"detector {name!r} needs the optional package {OPTIONAL_DETECTORS[name]!r}: "
                "pip install 'deckpose[peers]'"
            ) from None
        several = (" (one detector per call: run once for each, or use `bench-detectors` to "
                   "compare several)") if "," in name else ""
        raise ConfigError(
            f"unknown detector {name!r}{several}; choose one of {', '.join(sorted(_REGISTRY))}"
        ) from None
