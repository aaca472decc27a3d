"""Detection stage: sub-pixel beacon centroids and beacon identification.

* :mod:`~deckpose.detect.registry` — the detector interface (``Frame`` in,
  :class:`~deckpose.detect.registry.Blobs` out), options and registry;
* :mod:`~deckpose.detect.candidates` — coarse-to-fine candidate search with
  frame-adaptive thresholds (:mod:`~deckpose.detect.background`);
* detectors: ``binary`` and ``cog`` (:mod:`~deckpose.detect.centroid`),
  ``gauss`` (:mod:`~deckpose.detect.gauss`), ``log``
  (:mod:`~deckpose.detect.log_blobs`), ``opencv-blob``
  (:mod:`~deckpose.detect.opencv_blob`);
* :mod:`~deckpose.detect.identify` — beacon ids (ellipse RANSAC, homography,
  colour of the bow beacon);
* :mod:`~deckpose.detect.pipeline` — one frame: detect + identify ->
  :class:`~deckpose.records.Detections`;
* :mod:`~deckpose.detect.sources`, :mod:`~deckpose.detect.run`,
  :mod:`~deckpose.detect.tables` — datasets, image folders and Parquet tables;
* :mod:`~deckpose.detect.synthetic`, :mod:`~deckpose.detect.crb`,
  :mod:`~deckpose.detect.synthetic_dataset` — analytic spots, the centroid
  Cramér–Rao bound and a synthetic dataset for tests and benchmarks;
* :mod:`~deckpose.detect.benchmark`, :mod:`~deckpose.detect.bench_report` —
  ``deckpose bench-detectors``.
"""
