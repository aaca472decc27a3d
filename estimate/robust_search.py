"""The robust search of the frames a batch does not settle: outliers removed by leave-one-out.

For the frames an estimator's batch does not settle (:mod:`~estimate.frames_driver`): a
spurious point or a wrong id shows in its Mahalanobis reprojection residual, and the
search removes, one at a time, the point whose removal fits best. Each frame's search is
its own sequence of steps (:func:`_search_steps`, the one home of the rule), and
:func:`estimate_robustly` runs the steps of all the frames together: every frame that
waits for a solve or a round of leave-one-out trials is stacked with the others of its
beacon set into one batch (:func:`~estimate.observations.stack_frames`), so a run with
many such frames solves each round once per beacon set, and a lone frame is a batch of one.
It then makes each record (:func:`~estimate.pose_records.make_estimate`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Sequence
from typing import TYPE_CHECKING, Any, Literal, cast

import cv2
import numpy as np
from deckpose.estimate.least_squares import levenberg_marquardt
from deckpose.estimate.observations import (
    ObservationGroup,
    Observations,
    group_observations,
    observe_frame,
    stack_detections,
    stack_frames,
)
from deckpose.estimate.pose_candidates import Candidate
from deckpose.estimate.pose_records import covariance_scale, make_estimate

from deckpose.records import PoseEstimate

if TYPE_CHECKING:
    from deckpose.estimate.registry import EstimateOptions

    from deckpose.camera import CameraModel
    from deckpose.layout import DeckLayout
    from deckpose.records import Detections


#: ``solve(observations, frames) -> Candidate or failure reason of each frame``: the method's
#: solution of the frames ``frames`` (indices into :func:`estimate_robustly`'s detections)
#: whose observations of one beacon set are stacked in ``observations``.
SolveFn = Callable[[Observations, Sequence[int]], "list[Candidate | str]"]


#: A fit accepted under the widened outlier threshold must have a reprojection RMS of at most
#: this: a larger residual is no centroid error a covariance understates but wrong points.
SCALED_MAX_RMS_PX = 1.0


#: Levenberg-Marquardt iterations of a leave-one-out trial: a trial only ranks which point to
#: drop, from the current fit's pose.
TRIAL_ITERATIONS = 8


#: Numerical errors that end one frame's search with a failed record (not the run).
NUMERICAL_ERRORS = (np.linalg.LinAlgError, ValueError, ZeroDivisionError, cv2.error)


#: What a frame's search waits for: ``("solve", observations, None)`` -> its Candidate or
#: reason; ``("trial", observations, params (6,))`` -> chi2 of each subset without one point (M,).
Step = tuple[Literal["solve", "trial"], Observations, "np.ndarray | None"]
#: A frame's search result: (Candidate or failure reason, observations used, ids removed).
SearchResult = tuple["Candidate | str", Observations, list[int]]


def _search_steps(obs: Observations, *, min_points: int, outlier_chi2: float, max_outliers: int,
                  ) -> Generator[Step, Any, SearchResult]:
    """One frame's search: solve, and while a point's residual is an outlier remove the point whose removal fits best.

    A generator of the :data:`Step` it waits for (the driver, :func:`_run_searches`, sends
    back each answer). A point is an outlier when its squared Mahalanobis residual exceeds
    ``outlier_chi2``. When that leaves residuals too large after ``max_outliers``
    removals, and the first fit's :func:`covariance_scale` says the detections'
    covariances understate every residual alike (a clipped spot's centroid, say) while its
    reprojection RMS is at most :data:`SCALED_MAX_RMS_PX`, the search's fits are taken again
    at the threshold times that scale (the search at that threshold would remove the same
    points, only stop sooner). The plain search runs first because a least-squares fit
    smears a wrong id's residual over every point and would hide it in the scale.

    The leave-one-out trials are ranked from the current fit's pose (:data:`TRIAL_ITERATIONS`
    iterations, all subsets as one batch) instead of a full solve of each; the subset
    chosen is then solved in full. On garbage (19 points, three outliers allowed, both
    thresholds) full trials took 62 solves and up to 0.3 s a frame.

    Returns
    -------
    (Candidate or failure reason, observations used, ids removed)
    """
    first = (yield ("solve", obs, None)) if obs.n_points >= min_points else _too_few(obs, min_points)
    states: list[tuple[Candidate, Observations, list[int]]] = []
    result, used, removed, residual_failure = yield from _remove_outliers(
        obs, first, min_points=min_points, threshold=outlier_chi2, max_outliers=max_outliers, states=states)
    if not (residual_failure and isinstance(result, Candidate)):
        return result, used, removed
    # The scale from the fit without the worst points, where a wrong point no longer smears.
    pc = result.fit.point_chi2()[0]
    scale = float(covariance_scale(pc)) if np.isfinite(pc).all() else 1.0
    if scale <= 1.0:
        return result, used, removed
    # The search at the scaled threshold removes the same points in the same order (which
    # point to drop does not depend on the threshold); it only stops sooner: at the first
    # state of the search above whose residuals all lie within the scaled threshold. None
    # does: it gives up where the search above did.
    for c, c_obs, c_removed in states:
        c_pc = c.fit.point_chi2()[0]
        if c_pc.size == 0 or float(np.max(c_pc)) <= outlier_chi2 * scale:
            if float(c.fit.rms_px[0]) <= SCALED_MAX_RMS_PX:
                return c, c_obs, c_removed
            break
    return result, used, removed



def _remove_outliers(
    obs: Observations, result: Candidate | str, *, min_points: int, threshold: float, max_outliers: int,
    states: list[tuple[Candidate, Observations, list[int]]],
) -> Generator[Step, Any, tuple[Candidate | str, Observations, list[int], bool]]:
    """The leave-one-out search of :func:`_search_steps` at one threshold; the flag says
    whether it gave up with a residual above the threshold. ``states`` collects every fit
    the search went through, with its observations and the ids removed so far."""
    removed: list[int] = []
    while isinstance(result, Candidate):
        states.append((result, obs, list(removed)))
        pc = result.fit.point_chi2()[0]
        if pc.size == 0 or float(np.max(pc)) <= threshold:
            return result, obs, removed, False
        if len(removed) >= max_outliers or obs.n_points - 1 < min_points:
            worst = int(obs.ids[int(np.argmax(pc))])
            return Candidate(result.fit, result.extras, (
                f"reprojection residual of beacon {worst} is {math.sqrt(float(np.max(pc))):.1f} sigma "
                f"after removing {len(removed)} outlier(s): spurious point, wrong id, or sigma_px too small"
            )), obs, removed, True
        chi2 = yield ("trial", obs, result.fit.params[0])
        if not (chi2.size and np.isfinite(chi2.min())):
            return result, obs, removed, False
        drop = int(np.argmin(chi2))
        keep = np.ones(obs.n_points, dtype=bool)
        keep[drop] = False
        chosen = yield ("solve", obs.points(keep), None)
        if not isinstance(chosen, Candidate):
            return result, obs, removed, False
        removed.append(int(obs.ids[drop]))
        obs = obs.points(keep)
        result = chosen
    return result, obs, removed, False



def _too_few(obs: Observations, min_points: int) -> str:
    return f"too few identified beacons: {obs.n_points} usable, this method needs at least {min_points}"



def _trial_chi2(obs: Observations, params: np.ndarray) -> np.ndarray:
    """chi2 of each frame's subsets without one point, (F, M), after :data:`TRIAL_ITERATIONS` LM
    iterations from each frame's ``params`` (F, 6): all subsets of all frames as one batch, the
    left-out point given zero weight (it must still lie in front of the camera)."""
    F, M = len(obs), obs.n_points
    sqrt_info = np.repeat(np.broadcast_to(obs.sqrt_info, (F, M, 2, 2)), M, axis=0)  # row f*M+i: frame f without i
    trial = np.arange(F * M)
    sqrt_info[trial, trial % M] = 0.0
    rows = np.repeat(np.arange(F), M)
    stacked = Observations(obs.ids, obs.points_deck_m, obs.xy[rows], sqrt_info, obs.px_from_norm[rows],
                           obs.R_world_from_cam[rows])
    fit = levenberg_marquardt(np.repeat(np.asarray(params, float), M, axis=0), stacked,
                              max_iterations=TRIAL_ITERATIONS)
    return np.where(np.isfinite(fit.chi2), fit.chi2, np.inf).reshape(F, M)



def _answer(kind: str, obs: Observations, params: np.ndarray | None, frames: Sequence[int],
            solve: SolveFn) -> list[Any]:
    """The answers to one kind of step of ``frames``, whose observations ``obs`` are stacked."""
    if kind == "solve":
        return solve(obs, frames)
    assert params is not None
    return list(_trial_chi2(obs, params))


def _run_searches(searches: dict[int, Generator[Step, Any, SearchResult]], solve: SolveFn
                  ) -> dict[int, SearchResult | Exception]:
    """Run every frame's search to its end, each round's steps stacked by kind and beacon set.

    A numerical error in a stacked step is looked for frame by frame: the frame whose step
    raises ends with the error, the others go on.
    """
    out: dict[int, SearchResult | Exception] = {}
    waiting: dict[int, Step] = {}

    def send(f: int, answer: Any = None, error: Exception | None = None) -> None:
        try:
            search = searches[f]
            waiting[f] = search.throw(error) if error is not None else search.send(answer)
        except StopIteration as stop:
            out[f] = stop.value
        except NUMERICAL_ERRORS as exc:
            out[f] = exc

    for f in searches:
        send(f)
    while waiting:
        this_round, waiting = waiting, {}
        batches: dict[tuple[str, bytes], list[int]] = {}
        for f, (kind, obs, _) in this_round.items():
            batches.setdefault((kind, obs.ids.tobytes()), []).append(f)
        for (kind, _), frames in batches.items():
            steps = [this_round[f] for f in frames]
            params = None if kind == "solve" else np.stack([cast(np.ndarray, s[2]) for s in steps])
            try:
                answers = _answer(kind, stack_frames([s[1] for s in steps]), params, frames, solve)
            except NUMERICAL_ERRORS as exc:
                if len(frames) == 1:
                    send(frames[0], error=exc)
                    continue
                for f, s in zip(frames, steps, strict=True):  # which frame raised: each alone
                    try:
                        one = _answer(kind, s[1], None if s[2] is None else s[2][None], [f], solve)
                    except NUMERICAL_ERRORS as exc_f:
                        send(f, error=exc_f)
                    else:
                        send(f, one[0])
                continue
            for f, a in zip(frames, answers, strict=True):
                send(f, a)
    return out



def estimate_robustly(
    method: str,
    solve: SolveFn,
    detections: Sequence[Detections],
    camera: CameraModel,
    layout: DeckLayout,
    options: EstimateOptions,
    R_world_from_cam: np.ndarray,
    *,
    min_points: int,
    refined: bool,
    failure_prefix: str = "numerical failure",
) -> list[PoseEstimate]:
    """The robust search's records of many frames: the shared frame of every least-squares estimator here.

    Builds the frames' observations, runs every frame's search (outlier removal) with the
    steps of all frames stacked by beacon set, and turns each result into a
    :class:`PoseEstimate`; a numerical exception becomes that frame's failed estimate, whose
    reason starts with ``failure_prefix``.

    Parameters
    ----------
    method : str
    solve : callable
        :data:`SolveFn`.
    detections : sequence of F Detections
    camera, layout, options
    R_world_from_cam : (F, 3, 3) array of float
        Each frame's camera attitude.
    min_points : int, keyword-only
        Fewest points the method solves from.
    refined : bool, keyword-only
        The records' ``refined`` extra.
    failure_prefix : str, keyword-only

    Returns
    -------
    list of F PoseEstimate
    """
    R_wc = np.asarray(R_world_from_cam, dtype=float)
    out: list[PoseEstimate | None] = [None] * len(detections)
    frames: dict[int, tuple[Observations, int]] = {}
    with np.errstate(all="ignore"):
        for f, group_or_error in enumerate(_observe(detections, camera, layout, options, R_wc)):
            if isinstance(group_or_error, Exception):
                out[f] = PoseEstimate.failed(method, f"{failure_prefix}: {group_or_error}")
            else:
                frames[f] = group_or_error
        searches = {f: _search_steps(obs, min_points=min_points, outlier_chi2=options.outlier_chi2,
                                     max_outliers=options.max_outliers) for f, (obs, _) in frames.items()}
        results = _run_searches(searches, solve)
        for f, (_, n_ignored) in frames.items():
            r = results[f]
            if isinstance(r, Exception):
                out[f] = PoseEstimate.failed(method, f"{failure_prefix}: {r}")
                continue
            result, used, removed = r
            try:
                out[f] = make_estimate(method, result, used, n_ignored, removed,
                                       max_reprojection_rms_px=options.max_reprojection_rms_px, refined=refined)
            except NUMERICAL_ERRORS as exc:
                out[f] = PoseEstimate.failed(method, f"{failure_prefix}: {exc}")
    return cast("list[PoseEstimate]", out)  # (every frame has its record: failed, or from its search)



def _observe(detections: Sequence[Detections], camera: CameraModel, layout: DeckLayout,
             options: EstimateOptions, R_world_from_cam: np.ndarray) -> list[tuple[Observations, int] | Exception]:
    """Each frame's observations (a batch of one) and ignored detections, or the numerical error
    that building them raised (looked for frame by frame when the frames' batch raises)."""
    kwargs = {"sigma_px": options.sigma_px, "use_detection_covariance": options.use_detection_covariance}
    try:
        groups: list[ObservationGroup] = group_observations(stack_detections(detections), camera, layout,
                                                            R_world_from_cam, **kwargs)
    except NUMERICAL_ERRORS:
        return [_observe_one(d, camera, layout, R, kwargs) for d, R in zip(detections, R_world_from_cam)]
    by_frame: dict[int, tuple[Observations, int]] = {}  # (every frame is in exactly one group)
    for g in groups:
        lone = g.frames.size == 1
        for k, f in enumerate(g.frames.tolist()):
            by_frame[f] = (g.observations if lone else g.observations.take(np.array([k])), int(g.n_ignored[k]))
    return [by_frame[f] for f in range(len(detections))]


def _observe_one(d: Detections, camera: CameraModel, layout: DeckLayout, R: np.ndarray,
                 kwargs: dict[str, Any]) -> tuple[Observations, int] | Exception:
    try:
        g = observe_frame(d, camera, layout, R, **kwargs)
    except NUMERICAL_ERRORS as exc:
        return exc
    return g.observations, int(g.n_ignored[0])
