"""Detection across worker processes gives the tables of one process (issue 20, item 5)."""

from __future__ import annotations

import pandas as pd
import pytest
from deckpose.detect.run import CHUNK_FRAMES, detect_frames
from deckpose.detect.sources import open_dataset
from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

from deckpose.cli import main
from deckpose.errors import ConfigError
from tests.detect.conftest import SMALL_CAMERA

#: Timing columns: they differ between any two runs.
TIMING = ["seconds", "cpu_seconds"]


@pytest.fixture(scope="module")
def dataset_of_three_chunks(tmp_path_factory):
    cfg = SyntheticDatasetConfig(cameras=(SMALL_CAMERA,), heights_m=(18.0, 25.0, 30.0),
                                 frames_per_config=CHUNK_FRAMES, glint_probability=0.5, seed=7)
    return write_synthetic_dataset(cfg, tmp_path_factory.mktemp("ds") / "three_chunks")


def test_two_workers_give_the_tables_of_one(dataset_of_three_chunks):
    fs = open_dataset(dataset_of_three_chunks)
    assert len(fs.sources) == 3 * CHUNK_FRAMES  # more than one chunk: the pool is used
    d1, f1 = detect_frames(fs, "cog", workers=1)
    d2, f2 = detect_frames(fs, "cog", workers=2)
    pd.testing.assert_frame_equal(d1, d2)
    pd.testing.assert_frame_equal(f1.drop(columns=TIMING), f2.drop(columns=TIMING))
    assert f1.frame_id.tolist() == [s.frame_id for s in fs.sources]
    assert f1.ok.all()


def test_a_plugin_detector_runs_in_the_workers(dataset_of_three_chunks, tmp_path, monkeypatch):
    # a file plugin: the workers (other processes) must import it as well
    plugin = tmp_path / "worker_plugin.py"
    plugin.write_text("from deckpose.detect import registry\n"
                      "from deckpose.detect.cog import detect_cog\n"
                      "registry.register('worker-cog')(detect_cog)\n")
    out1, out2 = tmp_path / "one", tmp_path / "two"
    try:
        for out, w in ((out1, "1"), (out2, "2")):
            assert main(["detect", str(dataset_of_three_chunks), "--detector", "worker-cog", "--plugin",
                         str(plugin), "-o", str(out), "--workers", w, "--no-progress"]) == 0
    finally:
        from deckpose.detect import registry

        registry.unregister("worker-cog")
    pd.testing.assert_frame_equal(pd.read_parquet(out1 / "detections.parquet"),
                                  pd.read_parquet(out2 / "detections.parquet"))


def test_zero_workers_detect_in_this_process_and_negative_ones_are_refused(dataset_of_three_chunks, monkeypatch):
    import deckpose.detect.run as run_mod

    fs = open_dataset(dataset_of_three_chunks)
    monkeypatch.setattr("concurrent.futures.ProcessPoolExecutor",
                        lambda *a, **k: pytest.fail("workers=0 started a process pool"))
    d0, _ = run_mod.detect_frames(fs, "cog", workers=0)
    assert len(d0)
    with pytest.raises(ConfigError, match="workers must be >= 0"):
        detect_frames(fs, "cog", workers=-1)
