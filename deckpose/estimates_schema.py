"""The estimates table's columns: one schema for every method.

Every estimates table (``RUN/estimates/<detector>--<method>.parquet``, ``deckpose
estimate -o``) has exactly :data:`ESTIMATE_COLUMNS`, in order, with their types,
whatever the method: a value a method does not give is null (NaN in pandas), so a
run's estimates read together by glob (``pl.read_parquet("RUN/estimates/*.parquet")``,
DuckDB's ``read_parquet('RUN/estimates/*.parquet')``).

Angles are in degrees, as everywhere in tables, except the covariance (radians and
metres, ``cov_roll_rad__pitch_rad``) and the camera-relative rotation vector (OpenCV's
``rvec``, radians). A column that holds an estimator's extra names the
:attr:`~deckpose.records.PoseEstimate.extras` key (``Column.extra``; radians there,
degrees here). Extras of a plugin estimator that no column holds go, as a JSON object,
into the last column, ``extras_json``: the schema stays one schema, and nothing an
estimator reports is dropped.
"""

from __future__ import annotations

from itertools import combinations_with_replacement

from deckpose.records import POSE_PARAMS
from deckpose.table_schemas import Column, column

__all__ = ["COVARIANCE_COLUMNS", "ESTIMATE_COLUMNS", "EXTRAS_JSON", "MAX_OUTLIER_IDS", "SIGMA_COLUMNS"]

#: How many removed outliers' beacon ids an estimate records (``outlier_id_0`` ...).
MAX_OUTLIER_IDS = 8
#: The column of a plugin estimator's other extras (a JSON object; null when none).
EXTRAS_JSON = "extras_json"

_C = column
_PARAM_WORDS = {"roll_rad": "roll", "pitch_rad": "pitch", "yaw_rad": "yaw", "surge_m": "surge",
                "sway_m": "sway", "height_m": "height"}


def _table_name(param: str) -> str:
    """``roll_rad`` -> ``roll_deg`` (tables give angles in degrees); metres stay."""
    return param[: -len("_rad")] + "_deg" if param.endswith("_rad") else param


def _unit(param: str) -> str:
    return "deg" if param.endswith("_rad") else "m"


def _pose_group(prefix: str, what: str) -> tuple[Column, ...]:
    """Six columns ``<prefix><param>`` holding extras of the same name (degrees for angles)."""
    return tuple(_C(prefix + _table_name(p), "float64", _unit(p), f"{_PARAM_WORDS[p]} {what}",
                    extra=prefix + p) for p in POSE_PARAMS)


def _cov_unit(a: str, b: str) -> str:
    ua, ub = a.rsplit("_", 1)[1], b.rsplit("_", 1)[1]
    return f"{ua}^2" if ua == ub else f"{ua} {ub}"


#: The covariance's upper triangle: ``(column, row index, column index)`` over POSE_PARAMS.
COVARIANCE_COLUMNS: tuple[tuple[str, int, int], ...] = tuple(
    (f"cov_{POSE_PARAMS[i]}__{POSE_PARAMS[j]}", i, j)
    for i, j in combinations_with_replacement(range(len(POSE_PARAMS)), 2)
)
#: The standard deviations, from the covariance's diagonal (degrees and metres).
SIGMA_COLUMNS = tuple("sigma_" + _table_name(p) for p in POSE_PARAMS)

_BASE = (
    _C("frame_id", "int64", "", "the frame estimated (frames.parquet's frame_id)", nullable=False),
    _C("method", "string", "", "method label: estimator and variant (thesis, conic+refine, pnp+mean)",
       nullable=False),
    _C("ok", "bool", "", "the estimate can be trusted; if not, reason says why", nullable=False),
    _C("reason", "string", "", "why not ok (empty when ok)", nullable=False),
    _C("roll_deg", "float64", "deg", "deck roll, ZYX (R_world_from_deck = Rz(yaw) Ry(pitch) Rx(roll)); "
       "null where the method gives none"),
    _C("pitch_deg", "float64", "deg", "deck pitch, ZYX"),
    _C("yaw_deg", "float64", "deg", "deck yaw, ZYX"),
    _C("surge_m", "float64", "m", "deck centre minus camera position, world x (null for thesis)"),
    _C("sway_m", "float64", "m", "deck centre minus camera position, world y (null for thesis)"),
    _C("height_m", "float64", "m", "camera above the deck centre, world z"),
)
_SIGMAS = tuple(_C(name, "float64", _unit(p), f"standard deviation of {_PARAM_WORDS[p]} (the covariance's "
                   "diagonal); null without a covariance") for name, p in zip(SIGMA_COLUMNS, POSE_PARAMS))
_COVARIANCE = tuple(_C(name, "float64", _cov_unit(POSE_PARAMS[i], POSE_PARAMS[j]),
                       f"pose covariance, {_PARAM_WORDS[POSE_PARAMS[i]]} x {_PARAM_WORDS[POSE_PARAMS[j]]} "
                       "(radians and metres); null without a covariance")
                    for name, i, j in COVARIANCE_COLUMNS)
_FIT = (
    _C("n_points", "int64", "", "beacons the fit used (after outlier removal); null for thesis",
       extra="n_points"),
    _C("n_ignored", "int64", "", "detections not used: unassigned, unknown id, non-finite", extra="n_ignored"),
    _C("n_outliers_removed", "int64", "", "points removed as outliers (spurious point or wrong id)",
       extra="n_outliers_removed"),
    *(_C(f"outlier_id_{k}", "int64", "", f"beacon id of removed outlier {k} (0 = removed first); "
         "null if fewer were removed", extra=f"outlier_id_{k}") for k in range(MAX_OUTLIER_IDS)),
    _C("reprojection_rms_px", "float64", "px", "RMS reprojection residual of the fit",
       extra="reprojection_rms_px"),
    _C("chi2", "float64", "", "sum of squared whitened reprojection residuals", extra="chi2"),
    _C("dof", "int64", "", "degrees of freedom of chi2 (2 n_points - 6)", extra="dof"),
    _C("covariance_scale", "float64", "", "factor the covariance was widened by, as the residuals exceed the "
       "detections' covariances; null if not widened", extra="covariance_scale"),
)
_FLAGS = (
    _C("refined", "bool", "", "the pose is the iterated maximum-likelihood fit (pnp always; conic and "
       "thesis with +refine)", extra="refined"),
    _C("posterior_mean", "bool", "", "+mean: the pose is the posterior mean (false: the frame kept its "
       "ML pose, a poor posterior sample); null without +mean", extra="posterior_mean"),
    _C("centre_beacon_used", "bool", "", "conic: the centre beacon was among the points",
       extra="centre_beacon_used"),
    _C("assumed_level_deck", "bool", "", "the two-fold ambiguity was unresolved and the more level deck "
       "taken (assume_level_deck); null otherwise", extra="assumed_level_deck"),
)
_ALT_WHAT = "of the planar two-fold ambiguity's second solution"
_AMBIGUITY = (
    _C("n_solutions", "int64", "", "valid solutions of the planar two-fold ambiguity (conic, pnp)",
       extra="n_solutions"),
    _C("ambiguity_delta_chi2", "float64", "", "chi2 of the second solution minus the chosen one's",
       extra="ambiguity_delta_chi2"),
    _C("ambiguity_mahalanobis", "float64", "", "distance of the second solution in the chosen one's "
       "covariance, sigmas", extra="ambiguity_mahalanobis"),
    *(c for c in _pose_group("alt_", _ALT_WHAT) if not c.name.startswith(("alt_surge", "alt_sway"))),
    _C("ippe_error_ratio", "float64", "", "pnp: reprojection error of IPPE's second solution over its "
       "first's", extra="ippe_error_ratio"),
    *(c for c in _pose_group("ippe_alt_", "of IPPE's second solution, unrefined (pnp)")
      if not c.name.startswith(("ippe_alt_surge", "ippe_alt_sway"))),
)
_RELATIVE = (
    *(_C(f"rvec_cam_from_deck_{ax}_rad", "float64", "rad", f"R_cam_from_deck as an OpenCV rotation vector, "
         f"{ax}", extra=f"rvec_cam_from_deck_{ax}") for ax in "xyz"),
    *(_C(f"t_cam_from_deck_{ax}_m", "float64", "m", f"the deck centre in the camera frame, {ax}",
         extra=f"t_cam_from_deck_{ax}_m") for ax in "xyz"),
)
_THESIS = (
    _C("thesis_roll_deg", "float64", "deg", "thesis: roll in the thesis's convention (R = Rx Ry Rz)",
       extra="thesis_roll_deg"),
    _C("thesis_pitch_deg", "float64", "deg", "thesis: pitch in the thesis's convention",
       extra="thesis_pitch_deg"),
    _C("thesis_yaw_deg", "float64", "deg", "thesis: yaw in the thesis's convention", extra="thesis_yaw_deg"),
    _C("thesis_minor_axis_z", "float64", "", "thesis: Y''_z, the signed depth ratio of the ring's minor-axis "
       "point (sign(theta_u) (L1 + L2)/(L2 - L1)); its sign sets the sign of the thesis's beta", extra="yz2"),
)

#: Every column of an estimates table, in order (:mod:`deckpose.table_schemas`' :class:`Column`).
ESTIMATE_COLUMNS: tuple[Column, ...] = (
    *_BASE, *_SIGMAS, *_COVARIANCE, *_FIT, *_FLAGS, *_AMBIGUITY, *_RELATIVE,
    *_pose_group("untrusted_", "the fit gave, where not ok for want of trust (covariance undefined, "
                 "residuals too large)"),
    *_pose_group("unrefined_", "before +refine (of a method that does not iterate itself)"),
    *_pose_group("ml_", "of the maximum-likelihood pose the mean replaced (+mean)"),
    *_pose_group("posterior_sigma_", "posterior standard deviation (+mean)"),
    _C("posterior_effective_nodes", "float64", "", "+mean: effective number of posterior sample nodes "
       "(Kish); below 8 the ML pose is kept", extra="posterior_effective_nodes"),
    *_THESIS,
    _C("identified_by", "string", "", "how the frame's beacon ids were found: frame (the frame alone, as "
       "deckpose detect did), prior (matched to the beacons the last ok estimate of its time sequence predicts; "
       "deckpose estimate --run without --no-prior), none; null for a table estimated outside a run folder"),
    _C("prior_age_s", "float64", "s", "age of the prior estimate tried for identification (identified_by prior, "
       "or none where it failed); null where no prior was tried"),
    _C(EXTRAS_JSON, "string", "", "a plugin estimator's extras that no column holds, as a JSON object "
       "(non-finite values null); null when none"),
)
