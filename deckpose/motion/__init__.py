"""Ship motion: time series of deck pose (recorded, regular-wave or irregular-sea)."""

from deckpose.motion.series import MotionSeries, read_series, write_series

__all__ = ["MotionSeries", "read_series", "write_series"]
