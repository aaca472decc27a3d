"""An estimator's candidate poses for many frames, and the choice between them (the planar ambiguity).

A planar target seen by one camera can have two poses that fit almost equally
well. Every estimator here lists up to ``K`` solutions per frame
(:class:`BatchCandidates`); :func:`pick_batch` takes the lowest chi-square and says
whether the runner-up is told apart from it (:func:`ambiguity_resolved`, the one
home of that test). :func:`pick_candidates` turns that choice into each frame's
:class:`Candidate` as the robust search (:mod:`~estimate.robust_search`) takes it, with
the problem it reports when the ambiguity stays unresolved.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, overload

import numpy as np
from deckpose.estimate.least_squares import Fit, covariance_from_information, solve_batch
from numpy.typing import NDArray

from deckpose.rotation import wrap_angle_rad

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


@dataclass(frozen=True)
class Extra:
    """One method-specific extra for every frame of a batch.

    Attributes
    ----------
    name : str
    values : (F,) array of float
    present : (F,) array of bool or None
        Frames whose record carries this extra (None = all).
    """

    name: str
    values: FloatArray
    present: BoolArray | None = None


@dataclass(frozen=True)
class BatchCandidates:
    """The (up to K) solutions of one estimator for ``F`` frames.

    Attributes
    ----------
    fits : tuple of Fit
        Slot ``k`` of every frame, in the order the method lists its fits.
    valid : (F, K) array of bool
        Which slots hold a solution of that frame.
    unsolved : (F,) array of bool
        Frames without any solution (``reasons`` says why, where the method gives reasons).
    extras : tuple of Extra
        Method extras that precede ``n_solutions`` in the record, in order.
    choice : PickBatch or None
        :func:`pick_batch` of these solutions at the options' ``ambiguity_chi2``, where the
        method has made it already (:func:`finish_batch` makes it otherwise).
    reasons : tuple of str or None
        Why each frame has no solution (``""`` where it has one), where the method says;
        None where every frame has one or the method gives no reasons.
    """

    fits: tuple[Fit, ...]
    valid: BoolArray
    unsolved: BoolArray
    extras: tuple[Extra, ...] = ()
    choice: PickBatch | None = None
    reasons: tuple[str, ...] | None = None


def scatter_fit(n_frames: int, rows: NDArray[np.int64], fit: Fit) -> Fit:
    """A fit for ``n_frames`` frames holding ``fit`` at ``rows`` and an invalid fit elsewhere."""
    def put(a: np.ndarray, fill: float) -> np.ndarray:
        out = np.full((n_frames,) + a.shape[1:], fill, dtype=a.dtype)
        out[rows] = a
        return out

    return Fit(put(fit.params, np.nan), put(fit.chi2, np.inf), put(fit.information, np.nan),
                    put(fit.whitened, np.nan), put(fit.residuals_px, np.nan), put(fit.gradient, np.nan),
                    put(fit.iterations, 0), put(fit.converged, False))


def _take(a: np.ndarray, k: NDArray[np.int64]) -> np.ndarray:
    return a[np.arange(a.shape[0]), k]


def slot_values(fits: tuple[Fit, ...], attr: str, k: NDArray[np.int64]) -> np.ndarray:
    """``getattr(fits[k[f]], attr)[f]`` for every frame ``f`` (read-only: may be ``fits[0]``'s own array)."""
    if len(fits) == 1 or not k.any():
        return getattr(fits[0], attr)
    out = np.array(getattr(fits[0], attr))
    for j in range(1, len(fits)):
        rows = k == j
        if rows.any():
            out[rows] = getattr(fits[j], attr)[rows]
    return out


@dataclass(frozen=True)
class PickBatch:
    """Each frame's choice between its solutions (as candidates: :func:`pick_candidates`).

    Attributes
    ----------
    best : (F,) array of int
        Slot of the lowest-chi2 valid solution.
    n_good : (F,) array of int
        Valid solutions (finite chi2 and parameters).
    params : (F, 6) array of float
        The best solution.
    covariance : (F, 6, 6) array of float
    covariance_ok : (F,) array of bool
    alt_params : (F, 6) array of float
        The runner-up (NaN without one).
    delta_chi2, mahalanobis : (F,) array of float
        Runner-up minus best chi2; their distance in the best's covariance.
    unresolved : (F,) array of bool
        A runner-up fits almost as well (delta chi2 below the threshold) but differs
        by more than 3 sigma, or the distance could not be computed.
    alt : (F,) array of int
        Slot of the runner-up (meaningful where ``n_good >= 2``).
    """

    best: NDArray[np.int64]
    n_good: NDArray[np.int64]
    params: FloatArray
    covariance: FloatArray
    covariance_ok: BoolArray
    alt_params: FloatArray
    delta_chi2: FloatArray
    mahalanobis: FloatArray
    unresolved: BoolArray
    alt: NDArray[np.int64]


#: The planar ambiguity's two solutions are one pose when their Mahalanobis distance (in the
#: best fit's covariance) is at most this.
AMBIGUITY_SIGMAS = 3.0


@overload
def ambiguity_resolved(delta_chi2: float, mahalanobis: float, ambiguity_chi2: float) -> bool: ...


@overload
def ambiguity_resolved(delta_chi2: NDArray[np.float64], mahalanobis: NDArray[np.float64],
                       ambiguity_chi2: float) -> NDArray[np.bool_]: ...


def ambiguity_resolved(delta_chi2: Any, mahalanobis: Any, ambiguity_chi2: float) -> Any:
    """Whether the best solution is told from the runner-up: the one home of this test.

    Resolved when the runner-up's chi-square exceeds the best one's by at least
    ``ambiguity_chi2``, or the two poses lie within :data:`AMBIGUITY_SIGMAS` of each other.

    Parameters
    ----------
    delta_chi2, mahalanobis : float or (F,) array of float
        Runner-up minus best chi-square; the distance between the two poses.
    ambiguity_chi2 : float

    Returns
    -------
    bool or (F,) array of bool
        False where a value is NaN.
    """
    return (delta_chi2 >= ambiguity_chi2) | (mahalanobis <= AMBIGUITY_SIGMAS)


def pick_batch(cands: BatchCandidates, *, ambiguity_chi2: float) -> PickBatch:
    """Choose between each frame's solutions: the lowest chi2, and whether the ambiguity is resolved."""
    F, K = cands.valid.shape
    if K == 1:  # one solution per frame: nothing to order
        params, chi2 = cands.fits[0].params[:, None], cands.fits[0].chi2[:, None]
    else:
        params = np.stack([f.params for f in cands.fits], axis=1)  # (F, K, 6)
        chi2 = np.stack([f.chi2 for f in cands.fits], axis=1)
    good = cands.valid & np.isfinite(chi2) & np.isfinite(params).all(axis=2)
    n_good = good.sum(axis=1)
    order = (np.zeros((F, 1), dtype=np.int64) if K == 1
             else np.argsort(np.where(good, chi2, np.inf), axis=1, kind="stable"))
    kb = order[:, 0]
    best_p = cands.fits[0].params if K == 1 else _take(params, kb)
    cov, cov_ok = covariance_from_information(slot_values(cands.fits, "information", kb))
    unresolved = np.zeros(F, dtype=bool)
    if K < 2:  # no runner-up (one read-only NaN table serves its three fields)
        nan = np.full((F, 6), np.nan)
        return PickBatch(kb, n_good, best_p, cov, cov_ok, nan, nan[:, 0], nan[:, 0], unresolved, kb)
    has_alt = n_good >= 2
    ka = order[:, 1]
    alt_p = _take(params, ka)
    dchi2 = _take(chi2, ka) - _take(chi2, kb)
    delta = alt_p - best_p
    delta[:, :3] = wrap_angle_rad(delta[:, :3])
    testable = has_alt & cov_ok
    if testable.all():  # (every frame: no gathers)
        x, solved = solve_batch(cov, delta)
        maha = np.sqrt(np.sum(delta * x, axis=1))
        unresolved |= ~solved
    else:
        rows = np.flatnonzero(testable)
        maha = np.full(F, np.inf)
        if rows.size:
            x, solved = solve_batch(cov[rows], delta[rows])
            maha[rows] = np.sqrt(np.sum(delta[rows] * x, axis=1))
            unresolved[rows[~solved]] = True
    with np.errstate(invalid="ignore"):
        resolved = ambiguity_resolved(dchi2, maha, ambiguity_chi2)
    unresolved |= has_alt & ~resolved
    return PickBatch(kb, n_good, best_p, cov, cov_ok, alt_p, dchi2, maha, unresolved, ka)


#: The ambiguity's extras, in the order of the record (:func:`pick_candidates`).
AMBIGUITY_EXTRAS = ("ambiguity_delta_chi2", "ambiguity_mahalanobis", "alt_roll_rad", "alt_pitch_rad",
                     "alt_yaw_rad", "alt_height_m")


@dataclass(frozen=True)
class Candidate:
    """A solution of one estimator on one set of observations.

    Attributes
    ----------
    fit : Fit
        Of one frame (``F = 1``).
    extras : dict of str to float
        Method-specific diagnostics.
    problem : str
        Non-empty when the solution must not be trusted (e.g. unresolved ambiguity).
    """

    fit: Fit
    extras: dict[str, float] = field(default_factory=dict)
    problem: str = ""


def candidate_extras(cands: BatchCandidates, choice: PickBatch, *, n_solutions: bool = True
                     ) -> list[dict[str, float]]:
    """Each frame's extras of its chosen solution, in the record's order: the one home of this part.

    The method's own extras (where present), ``n_solutions`` (unless ``n_solutions`` is
    False: a single solution taken as it is) and, where a runner-up exists, the
    ambiguity's (:data:`AMBIGUITY_EXTRAS`: its delta chi-square, Mahalanobis distance and
    attitude and height).

    Parameters
    ----------
    cands : BatchCandidates
        Of ``F`` frames.
    choice : PickBatch
        :func:`pick_batch` of ``cands``.
    n_solutions : bool, keyword-only

    Returns
    -------
    list of F dict of str to float
    """
    F = cands.valid.shape[0]
    pre = [(e.name, e.values.tolist(), None if e.present is None else e.present.tolist()) for e in cands.extras]
    n_sol = choice.n_good.tolist()
    alt = (choice.n_good >= 2).tolist()
    amb_rows = (np.column_stack([choice.delta_chi2, choice.mahalanobis, choice.alt_params[:, :3],
                                 choice.alt_params[:, 5]]).tolist() if any(alt) else [])
    out: list[dict[str, float]] = []
    for i in range(F):
        ex: dict[str, float] = {}
        for name, vals, present in pre:
            if present is None or present[i]:
                ex[name] = vals[i]
        if n_solutions:
            ex["n_solutions"] = float(n_sol[i])
        if alt[i]:
            ex.update(zip(AMBIGUITY_EXTRAS, amb_rows[i]))
        out.append(ex)
    return out


def pick_candidates(cands: BatchCandidates, *, ambiguity_chi2: float, assume_level_deck: bool,
                    no_solution: str) -> list[Candidate | str]:
    """Each frame's choice between its solutions (the planar ambiguity), as the robust search takes it.

    :func:`pick_batch` of the frames: the lower chi-square wins. When the runner-up is
    within ``ambiguity_chi2`` of it while the two poses differ by more than
    :data:`AMBIGUITY_SIGMAS` (Mahalanobis, best fit's covariance), the ambiguity is
    unresolved: the candidate carries a problem, or, with ``assume_level_deck``, the more
    level deck is chosen and ``extras["assumed_level_deck"] = 1`` says so.

    Parameters
    ----------
    cands : BatchCandidates
        Of ``F`` frames.
    ambiguity_chi2 : float, keyword-only
    assume_level_deck : bool, keyword-only
    no_solution : str, keyword-only
        The reason of an unsolved frame where the method gives none (:attr:`BatchCandidates.reasons`).

    Returns
    -------
    list of F Candidate or str
        Each frame's chosen solution (its fits a batch of one) with the frame's extras, or why
        there is none.
    """
    F = cands.valid.shape[0]
    if not cands.fits:  # no frame has a solution
        return [cands.reasons[f] if cands.reasons is not None else no_solution for f in range(F)]
    choice = pick_batch(cands, ambiguity_chi2=ambiguity_chi2)
    extras = candidate_extras(cands, choice)
    out: list[Candidate | str] = []
    for f, (unsolved, n_good) in enumerate(zip(cands.unsolved.tolist(), choice.n_good.tolist(), strict=True)):
        if unsolved:
            out.append(cands.reasons[f] if cands.reasons is not None else no_solution)
            continue
        if n_good == 0:
            out.append("no valid pose solution (points behind the camera or non-finite fit)")
            continue
        frame_fits = tuple(fit.frame(f) for fit in cands.fits)
        out.append(_frame_choice(choice, f, n_good, frame_fits, extras[f], ambiguity_chi2=ambiguity_chi2,
                                 assume_level_deck=assume_level_deck))
    return out


def _frame_choice(choice: PickBatch, f: int, n_good: int, fits: tuple[Fit, ...], ex: dict[str, float], *,
                  ambiguity_chi2: float, assume_level_deck: bool) -> Candidate:
    """Frame ``f``'s candidate from ``choice`` (``fits``: its own solutions, each a batch of one;
    ``ex``: its :func:`candidate_extras`)."""
    best = fits[int(choice.best[f])]
    if n_good == 1:
        return Candidate(best, ex)
    alt = fits[int(choice.alt[f])]
    dchi2, maha = float(choice.delta_chi2[f]), float(choice.mahalanobis[f])
    if not choice.unresolved[f]:
        return Candidate(best, ex)
    if assume_level_deck:
        b, a = best.params[0], alt.params[0]
        ex["assumed_level_deck"] = 1.0
        if math.cos(b[0]) * math.cos(b[1]) >= math.cos(a[0]) * math.cos(a[1]):
            return Candidate(best, ex)
        # The runner-up is chosen: "alt_*" now describe the rejected (lower chi2) solution.
        ex.update(alt_roll_rad=float(b[0]), alt_pitch_rad=float(b[1]), alt_yaw_rad=float(b[2]),
                  alt_height_m=float(b[5]))
        return Candidate(alt, ex)
    return Candidate(best, ex, (
        f"two-fold planar ambiguity unresolved: the second solution fits almost as well "
        f"(delta chi2 = {dchi2:.2f} < {ambiguity_chi2}) but differs by {maha:.1f} sigma; "
        "add beacons (the centre beacon) or set assume_level_deck"))
