"""Shared fixtures of the detection tests: small analytic-spot frames and datasets."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from deckpose.detect.synthetic_dataset import SyntheticDatasetConfig, write_synthetic_dataset

#: A camera of 640x360 px with the thesis focal angle sees the standard ring from 18-25 m
#: with beacons of ~1.9-2.6 px radius.
SMALL_CAMERA = "640x360"


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """4 RGB frames: 2 heights x 2 frames, each with one hidden beacon and one glint."""
    cfg = SyntheticDatasetConfig(
        cameras=(SMALL_CAMERA,),
        heights_m=(18.0, 25.0),
        frames_per_config=2,
        glint_probability=1.0,
        hide_probability=1.0,
        seed=3,
    )
    return write_synthetic_dataset(cfg, tmp_path_factory.mktemp("ds") / "tiny")


def grid_points(rng: np.random.Generator, shape: tuple[int, int], n_u: int, n_v: int) -> np.ndarray:
    """Spot centres on a jittered grid (well separated), (n_u * n_v, 2)."""
    H, W = shape
    us = (np.arange(n_u) + 0.5) * W / n_u
    vs = (np.arange(n_v) + 0.5) * H / n_v
    pts = np.array([[u, v] for u in us for v in vs], float)
    return pts + rng.uniform(-0.5, 0.5, pts.shape)


@pytest.fixture
def two_lighting_dataset(tiny_dataset: Path, tmp_path: Path) -> Path:
    """A copy of ``tiny_dataset`` whose even frames are lit as night and odd ones as dusk."""
    import shutil

    import pandas as pd

    ds = tmp_path / "lit"
    shutil.copytree(tiny_dataset, ds)
    frames = pd.read_parquet(ds / "frames.parquet")
    frames["lighting"] = np.where(frames.frame_id % 2 == 0, "night", "dusk")
    frames.to_parquet(ds / "frames.parquet")
    return ds
