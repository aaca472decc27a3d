"""Topic and frame names of a run's MCAP log: one home for the names the log writes and its layout reads.

* ``/errors/<detector>--<method>``: per-frame errors (``deckpose evaluate``'s);
* ``/estimates/<detector>--<method>``: the per-frame estimates (pose, sigmas, ok, reason);
* ``/truth/deck``: the true deck pose of each frame (roll, pitch, yaw, heave, surge, sway);
* ``/tracks/<detector>--<method>--<tracker>``: the filtered states of ``deckpose track``;
* ``/predictions/<detector>--<method>--<tracker>/<horizon>``: what the filter predicted for this
  frame one horizon earlier (:func:`deckpose.tracking.due_predictions.predictions_due`);
* transforms ``deck_est/<detector>--<method>``, ``deck_track/<stem>`` and
  ``deck_pred/<stem>/<horizon>`` in ``/tf``.

Horizons are named ``<seconds>s`` with the decimal point as ``_`` (``0_5s``, ``2s``), so every
topic is a plain message path of ``[A-Za-z0-9_-]`` segments.
"""

from __future__ import annotations

from deckpose.run_folder import SEPARATOR

__all__ = [
    "TRUTH_DECK_TOPIC",
    "errors_topic",
    "estimate_frame",
    "estimates_topic",
    "horizon_name",
    "prediction_frame",
    "prediction_topic",
    "track_frame",
    "track_stem",
    "track_topic",
]

TRUTH_DECK_TOPIC = "/truth/deck"


def horizon_name(horizon_s: float) -> str:
    """A horizon as a name segment: ``0.5 -> '0_5s'``, ``2.0 -> '2s'``."""
    return f"{horizon_s:g}s".replace(".", "_").replace("-", "m")


def track_stem(detector: str, method: str, tracker: str) -> str:
    """``<detector>--<method>--<tracker>``, as the track's files are named."""
    return f"{detector}{SEPARATOR}{method}{SEPARATOR}{tracker}"


def errors_topic(detector: str, method: str) -> str:
    return f"/errors/{detector}{SEPARATOR}{method}"


def estimates_topic(detector: str, method: str) -> str:
    return f"/estimates/{detector}{SEPARATOR}{method}"


def track_topic(stem: str) -> str:
    return f"/tracks/{stem}"


def prediction_topic(stem: str, horizon_s: float) -> str:
    return f"/predictions/{stem}/{horizon_name(horizon_s)}"


def estimate_frame(detector: str, method: str) -> str:
    return f"deck_est/{detector}{SEPARATOR}{method}"


def track_frame(stem: str) -> str:
    return f"deck_track/{stem}"


def prediction_frame(stem: str, horizon_s: float) -> str:
    return f"deck_pred/{stem}/{horizon_name(horizon_s)}"
