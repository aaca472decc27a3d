"""Ship motion: time series of deck pose (recorded, regular-wave or irregular-sea).

* :mod:`~deckpose.motion.series`: the :class:`MotionSeries` record and its CSV/Parquet files;
* :mod:`~deckpose.motion.ship`: ship particulars and presets (``thesis``, ``ffg7``);
* :mod:`~deckpose.motion.closed_form`: closed-form heave, pitch, roll in regular waves;
* :mod:`~deckpose.motion.thesis_series`: the thesis's 495-sample series, exactly;
* :mod:`~deckpose.motion.spectrum`: sea states and wave spectra;
* :mod:`~deckpose.motion.irregular`: seeded irregular-sea series and their predicted variances;
* :mod:`~deckpose.motion.filtered_noise`, :mod:`~deckpose.motion.offset`,
  :mod:`~deckpose.motion.plot`: yaw/drift noise, motion of an offset point, plots.
"""

from deckpose.motion.series import MotionSeries, read_series, write_series

__all__ = ["MotionSeries", "read_series", "write_series"]
