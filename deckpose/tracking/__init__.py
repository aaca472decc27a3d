"""Tracking and prediction: a deck-motion Kalman filter over a run's per-frame estimates.

* :mod:`~deckpose.tracking.deck_motion_model`: the model (wave-frequency oscillator banks for
  roll, pitch and heave; near-constant velocity for yaw, surge, sway and the UAV's height),
  discretised exactly;
* :mod:`~deckpose.tracking.kalman`: predict, and update in Joseph form with a Mahalanobis gate;
* :mod:`~deckpose.tracking.sequence_filter`: the filter over one time sequence of estimates;
* :mod:`~deckpose.tracking.prediction`: roll, pitch, heave and heave rate predicted ahead;
* :mod:`~deckpose.tracking.due_predictions`: each prediction placed at the frame it was made for;
* :mod:`~deckpose.tracking.landing_window`: the landing-window indicator and its truth;
* :mod:`~deckpose.tracking.measurements`: estimates tables as measurements;
* :mod:`~deckpose.tracking.config`, :mod:`~deckpose.tracking.run`: the tracker's config and
  ``deckpose track``'s entry point (:func:`track_run`).
"""

from typing import TYPE_CHECKING

from deckpose.lazy_api import lazy_api

__all__ = [
    "DeckMotionModel",
    "FilterTrack",
    "LandingLimits",
    "TrackConfig",
    "TrackRunResult",
    "filter_sequence",
    "kalman_predict",
    "kalman_update",
    "landing_window_go",
    "load_track_config",
    "predict_outputs",
    "predictions_due",
    "track_run",
    "track_table",
    "truth_window_calm",
]

_API: dict[str, str] = {
    "DeckMotionModel": "deckpose.tracking.deck_motion_model",
    "FilterTrack": "deckpose.tracking.sequence_filter",
    "filter_sequence": "deckpose.tracking.sequence_filter",
    "kalman_predict": "deckpose.tracking.kalman",
    "predictions_due": "deckpose.tracking.due_predictions",
    "kalman_update": "deckpose.tracking.kalman",
    "LandingLimits": "deckpose.tracking.landing_window",
    "landing_window_go": "deckpose.tracking.landing_window",
    "truth_window_calm": "deckpose.tracking.landing_window",
    "predict_outputs": "deckpose.tracking.prediction",
    "TrackConfig": "deckpose.tracking.config",
    "load_track_config": "deckpose.tracking.config",
    "TrackRunResult": "deckpose.tracking.run",
    "track_run": "deckpose.tracking.run",
    "track_table": "deckpose.tracking.run",
}

if TYPE_CHECKING:
    from deckpose.tracking.config import TrackConfig, load_track_config
    from deckpose.tracking.deck_motion_model import DeckMotionModel
    from deckpose.tracking.due_predictions import predictions_due
    from deckpose.tracking.kalman import kalman_predict, kalman_update
    from deckpose.tracking.landing_window import LandingLimits, landing_window_go, truth_window_calm
    from deckpose.tracking.prediction import predict_outputs
    from deckpose.tracking.run import TrackRunResult, track_run, track_table
    from deckpose.tracking.sequence_filter import FilterTrack, filter_sequence

__getattr__, __dir__ = lazy_api(__name__, _API)
