"""estimate and evaluate write the same files for any number of workers, and on Dask.

A fake run (12 frames, two cameras, tracked) is estimated and evaluated in this process
(workers 0), by one worker setting that stays here (1) and by two worker processes (2),
with the task sizes lowered so that its frames really are split into several tasks; the
tables are compared value by value and the files (log, layout, tables) byte by byte
against the in-process ones. Nothing in them holds a time stamp of the run, so they are
equal to the byte.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
import pytest
from deckpose.estimate import batch as estimate_batch
from deckpose.estimate import run as estimate_stage
from deckpose.estimate.registry import parse_method
from deckpose.evaluate import mcap_log
from deckpose.evaluate import run as evaluate_stage
from deckpose.evaluate.run import evaluate_run

from deckpose import run_folder as rl
from deckpose import worker_pool
from deckpose.cli import main
from deckpose.sequence_run import estimate_run_with_prior
from deckpose.tables import write_table
from deckpose.tracking.config import TrackConfig
from deckpose.tracking.run import track_table
from tests.evaluate.fake_run import make_fake_run

#: Methods whose tables are compared: the batched estimators (pnp under its posterior mean).
METHODS = ("thesis", "conic", "pnp+mean")
#: The files of the evaluate stage, compared byte by byte.
EVALUATED = ("evaluation/errors.parquet", "evaluation/resolution_tables.csv",
             "evaluation/resolution_tables.md", "log.mcap", "foxglove_layout.json")


@pytest.fixture(scope="module")
def fake_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fake run with thesis estimates tracked over time (so the log has tracks and predictions)."""
    root = make_fake_run(tmp_path_factory.mktemp("workers") / "run")
    assert main(["estimate", "--run", str(root), "--detector", "fake", "--method", "thesis", "--workers", "0"]) == 0
    run = rl.run_paths(root)
    tracks, preds = track_table(rl.read_frames(run), rl.read_estimates(run, "fake", "thesis"),
                                TrackConfig(horizons_s=(0.1, 0.2)))
    run.tracks_dir.mkdir()
    write_table(tracks, run.tracks("fake", "thesis", "wave-bank"), "tracks")
    write_table(preds, run.track_predictions("fake", "thesis", "wave-bank"), "track predictions")
    return root


@pytest.fixture
def small_tasks(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Batches and tasks of 2 frames (the log's of 4), and the number of tasks of each map_ordered call."""
    monkeypatch.setattr(estimate_batch, "CHUNK_FRAMES", 2)  # the estimators' batches, here and in tasks
    monkeypatch.setattr(estimate_stage, "MIN_PARALLEL_FRAMES", 1)
    monkeypatch.setattr(evaluate_stage, "MIN_CRB_TASK_FRAMES", 2)
    monkeypatch.setattr(mcap_log, "LOG_TASK_FRAMES", 4)
    monkeypatch.setattr(mcap_log, "MIN_PARALLEL_LOG_FRAMES", 1)
    counts: list[int] = []
    real = worker_pool.map_ordered

    def counting(fn, tasks, **kw):
        counts.append(len(tasks))
        return real(fn, tasks, **kw)

    monkeypatch.setattr(worker_pool, "map_ordered", counting)
    monkeypatch.setattr(mcap_log, "map_ordered", counting)
    return counts


def _estimates(root: Path, workers: int, scheduler: str | None = None) -> dict[str, pd.DataFrame]:
    return {m: estimate_run_with_prior(root, parse_method(m), detector="fake", workers=workers,
                                       scheduler=scheduler).table for m in METHODS}


def _evaluate(root: Path, workers: int, scheduler: str | None = None) -> dict[str, bytes]:
    evaluate_run(rl.run_paths(root), preview_px=256, workers=workers, scheduler=scheduler)
    return {name: (root / name).read_bytes() for name in EVALUATED}


def test_estimate_and_evaluate_are_the_same_for_0_1_and_2_workers(fake_run: Path, tmp_path: Path,
                                                                  small_tasks: list[int]) -> None:
    roots = {}
    for workers in (0, 1, 2):
        roots[workers] = tmp_path / f"w{workers}"
        shutil.copytree(fake_run, roots[workers])
    estimates, files = {}, {}
    for w, root in roots.items():
        small_tasks.clear()
        estimates[w] = _estimates(root, w)
        files[w] = _evaluate(root, w)
        if w < 2:  # estimated here; the bounds and the log in one task each
            assert small_tasks == [1, 1], small_tasks
        else:  # each camera's 6 frames in 3 batches (per method), the 12 bounds in 2, the log's in 3
            assert small_tasks == [6] * len(METHODS) + [2, 3], small_tasks
    for w in (1, 2):
        for m in METHODS:
            pd.testing.assert_frame_equal(estimates[w][m], estimates[0][m], check_exact=True)
        for name in EVALUATED:
            assert files[w][name] == files[0][name], f"{name} differs with {w} workers"
    errors = pd.read_parquet(roots[2] / "evaluation" / "errors.parquet")
    assert len(errors) == 12 * len(METHODS) and errors["crb_roll_deg"].notna().all()


def test_the_estimate_command_splits_a_table_across_workers(fake_run: Path, tmp_path: Path,
                                                             small_tasks: list[int]) -> None:
    """``deckpose estimate DETECTIONS --workers 2`` (no run folder): the same table as in this process."""
    table = fake_run / "detections" / "fake.parquet"
    camera = fake_run / "cameras" / "4mp-small.yaml"
    one_camera = tmp_path / "dets.parquet"
    frames = rl.read_frames(rl.run_paths(fake_run))
    ids = frames.loc[frames["camera"] == "4mp-small", "frame_id"]
    pd.read_parquet(table).loc[lambda d: d["frame_id"].isin(ids)].to_parquet(one_camera)
    out = {}
    for workers in (0, 2):
        out[workers] = tmp_path / f"est{workers}.parquet"
        assert main(["estimate", str(one_camera), "--camera", str(camera), "-o", str(out[workers]),
                     "--method", "pnp", "--workers", str(workers)]) == 0
    assert small_tasks == [3]  # 6 frames in tasks of 2 (workers 0 never gets there)
    pd.testing.assert_frame_equal(pd.read_parquet(out[2]), pd.read_parquet(out[0]), check_exact=True)


def test_a_negative_worker_count_is_refused(fake_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for argv in (["estimate", "--run", str(fake_run), "--detector", "fake", "--workers", "-1"],
                 ["evaluate", str(fake_run), "--workers", "-1"]):
        assert main(argv) != 0
        assert "--workers must be >= 0, got -1" in capsys.readouterr().err


@pytest.mark.slow
def test_on_dask_the_tables_are_the_same(fake_run: Path, tmp_path: Path, small_tasks: list[int]) -> None:
    distributed = pytest.importorskip("distributed")
    here, there = tmp_path / "here", tmp_path / "dask"
    shutil.copytree(fake_run, here)
    shutil.copytree(fake_run, there)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  local_directory=str(tmp_path / "scratch")) as lc:
        on_dask = _estimates(there, 0, lc.scheduler_address)
        files = _evaluate(there, 0, lc.scheduler_address)
    # each camera's 6 frames in 3 batches, the 12 bounds in 6 (not bounded by --workers); the log here
    assert small_tasks == [6] * len(METHODS) + [6, 1], small_tasks
    local = _estimates(here, 0)
    for m in METHODS:
        pd.testing.assert_frame_equal(on_dask[m], local[m], check_exact=True)
    assert files == _evaluate(here, 0)
