"""Detection stage: sub-pixel beacon centroids and beacon identification.

* :mod:`~deckpose.detect.registry` — the detector interface (``Frame`` in,
  :class:`~deckpose.detect.registry.Blobs` out), options and registry;
* :mod:`~deckpose.detect.candidates` — coarse-to-fine candidate search with
  frame-adaptive thresholds (:mod:`~deckpose.detect.background`), each found blob a
  :class:`~deckpose.detect.candidate.Candidate`;
* :mod:`~deckpose.detect.centroid` — the classic centroiders on one candidate;
* detectors: ``binary`` (:mod:`~deckpose.detect.binary`), ``cog``
  (:mod:`~deckpose.detect.cog`), ``gauss`` (:mod:`~deckpose.detect.gauss`), ``log``
  (:mod:`~deckpose.detect.log_blobs`), ``opencv-blob``
  (:mod:`~deckpose.detect.opencv_blob`);
* :mod:`~deckpose.detect.identify` — beacon ids of a frame alone: one ring
  (:mod:`~deckpose.detect.one_ring_identify`: :mod:`~deckpose.detect.ring_ellipse`
  RANSAC, :mod:`~deckpose.detect.ring_homography`, colour of the bow beacon) or two
  (:mod:`~deckpose.detect.two_ring_identify`), the record and options in
  :mod:`~deckpose.detect.identification`;
* :mod:`~deckpose.detect.guided_look` — a second look at the empty ring slots, in the
  beacon's colour, once the ring is fitted;
* :mod:`~deckpose.detect.prior_identify` — beacon ids from a prior pose (the
  previous frame's), for frames without a bow or a ring in view;
* :mod:`~deckpose.detect.frame_detection` — one frame: detect + identify ->
  :class:`~deckpose.records.Detections`;
* :mod:`~deckpose.detect.sources`, :mod:`~deckpose.detect.run`,
  :mod:`~deckpose.detect.tables` — datasets, image folders and Parquet tables;
* :mod:`~deckpose.detect.synthetic`, :mod:`~deckpose.detect.crb`,
  :mod:`~deckpose.detect.synthetic_dataset` — analytic spots, the centroid
  Cramér–Rao bound and a synthetic dataset for tests and benchmarks;
* :mod:`~deckpose.detect.benchmark`, :mod:`~deckpose.detect.bench_ranking`,
  :mod:`~deckpose.detect.bench_report` —
  ``deckpose bench-detectors``.
"""

from typing import TYPE_CHECKING

from deckpose.lazy_api import lazy_api

__all__ = [
    "Blobs",
    "DetectRunResult",
    "DetectorOptions",
    "FrameDetections",
    "IdentifyOptions",
    "PriorIdentifyOptions",
    "detect_frame",
    "detect_frames",
    "detect_run",
    "get",
    "identify_beacons",
    "identify_with_prior",
    "load_plugin",
    "names",
    "register",
]

#: Where each name of the stage API lives.
_API: dict[str, str] = {
    "Blobs": "deckpose.detect.registry",
    "DetectorOptions": "deckpose.detect.registry",
    "register": "deckpose.detect.registry",
    "names": "deckpose.detect.registry",
    "get": "deckpose.detect.registry",
    "load_plugin": "deckpose.detect.registry",
    "IdentifyOptions": "deckpose.detect.identify",
    "identify_beacons": "deckpose.detect.identify",
    "PriorIdentifyOptions": "deckpose.detect.prior_identify",
    "identify_with_prior": "deckpose.detect.prior_identify",
    "FrameDetections": "deckpose.detect.frame_detection",
    "detect_frame": "deckpose.detect.frame_detection",
    "DetectRunResult": "deckpose.detect.run",
    "detect_run": "deckpose.detect.run",
    "detect_frames": "deckpose.detect.run",
}

if TYPE_CHECKING:  # the same names for type checkers (at run time __getattr__ imports them)
    from deckpose.detect.frame_detection import FrameDetections, detect_frame
    from deckpose.detect.identify import IdentifyOptions, identify_beacons
    from deckpose.detect.prior_identify import PriorIdentifyOptions, identify_with_prior
    from deckpose.detect.registry import Blobs, DetectorOptions, get, load_plugin, names, register
    from deckpose.detect.run import DetectRunResult, detect_frames, detect_run

__getattr__, __dir__ = lazy_api(__name__, _API)
