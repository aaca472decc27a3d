"""Monte Carlo of the thesis's chapter-4 experiment for one table cell.

The set-up is the one that reproduces Tables 4.2-4.15 (reference page, "How the
thesis tables were produced"): the thesis camera (75 deg focal angle, non-square
form) at one resolution; the 495-sample regular-wave motion series; camera
distance = table height + heave; beacons outside the image dropped; eq. 4.1-4.3
noise of N px; the faithful estimator; errors against the true thesis angles.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from deckpose.camera import PixelForm, from_focal_angle, THESIS_RESOLUTIONS
from deckpose.errors import InputDataError
from deckpose.estimate.thesis_batch import Failure, estimate_thesis_batch
from deckpose.layout import thesis_layout
from deckpose.noise import thesis_uniform
from deckpose.projection import project_thesis_centred
from deckpose.rotation import R_from_thesis

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ThesisMotion:
    """The thesis's motion input: thesis-convention angles (deg) and heave per sample, shape (S,)."""

    roll_deg: FloatArray
    pitch_deg: FloatArray
    yaw_deg: FloatArray
    heave: FloatArray

    def __len__(self) -> int:
        return int(self.roll_deg.size)


def load_thesis_motion(path: str | Path | None = None) -> ThesisMotion:
    """Load ``thesis_motion_series.csv`` (embedded copy by default).

    Columns ``roll_deg, pitch_deg, yaw_deg, heave_m`` hold the thesis's own
    angles (``R = Rx(roll) Ry(pitch) Rz(yaw)``), not ZYX.
    """
    if path is None:
        src = resources.files("deckpose") / "data" / "thesis_motion_series.csv"
        with resources.as_file(src) as p:
            df = pd.read_csv(p)
    else:
        try:
            df = pd.read_csv(path)
        except OSError as exc:
            raise InputDataError(f"cannot read thesis motion file {path}: {exc}") from exc
    need = ["roll_deg", "pitch_deg", "yaw_deg", "heave_m"]
    missing = [c for c in need if c not in df.columns]
    if missing:
        raise InputDataError(f"{path}: missing column(s) {missing}")
    return ThesisMotion(*(df[c].to_numpy(float) for c in need))


@dataclass(frozen=True)
class CellSpec:
    """One cell of the tables: resolution preset name, noise N (px), table height (units)."""

    resolution: str
    noise_px: float
    height: float

    def __post_init__(self) -> None:
        if self.resolution not in THESIS_RESOLUTIONS:
            raise InputDataError(f"unknown resolution {self.resolution!r}; use {list(THESIS_RESOLUTIONS)}")


class Quantity(enum.IntEnum):
    ROLL = 0
    PITCH = 1
    YAW = 2
    HEIGHT = 3


@dataclass(frozen=True)
class CellResult:
    """Statistics of one cell.

    Attributes
    ----------
    max_abs : (4,) array of float
        Maximum absolute error of roll, pitch, yaw (deg) and height (units), ok images only.
    mean, sigma : (4,) array of float
        Mean and standard deviation of the same errors.
    rms_mean_px, rms_sigma_px : float
        Mean and sigma over images of the per-image noise RMS, pixels.
    yz2_within_sigma_pct, yz2_sign_pct : float
        Table 4.14 statistics of Y''_z against its noise-free value.
    n_images, n_ok : int
    failures : dict of str to int
        Count per failure reason name.
    """

    spec: CellSpec
    max_abs: FloatArray
    mean: FloatArray
    sigma: FloatArray
    rms_mean_px: float
    rms_sigma_px: float
    yz2_within_sigma_pct: float
    yz2_sign_pct: float
    n_images: int
    n_ok: int
    failures: dict[str, int] = field(default_factory=dict)


def thesis_camera(resolution: str):
    """The thesis camera of a resolution: 75 deg focal angle, eq. 1.8/1.9 (non-square)."""
    w, h = THESIS_RESOLUTIONS[resolution]
    return from_focal_angle(w, h, 75.0, form=PixelForm.THESIS, name=f"{resolution}-thesis")


def clean_projection(spec: CellSpec, motion: ThesisMotion) -> tuple[FloatArray, NDArray[np.bool_], FloatArray]:
    """Noise-free centred coordinates (S, 12, 2), visibility (S, 12) and distances (S,)."""
    cam = thesis_camera(spec.resolution)
    D = spec.height + motion.heave
    R = R_from_thesis(*np.radians([motion.roll_deg, motion.pitch_deg, motion.yaw_deg]))
    pc = project_thesis_centred(thesis_layout().positions_deck_m(), R, D, cam.fx, cam.fy)
    P = np.einsum("sij,nj->sni", R, thesis_layout().positions_deck_m())
    in_front = (D[:, None] - P[..., 2]) > 0
    vis = in_front & (np.abs(pc[..., 0]) <= cam.width_px / 2) & (np.abs(pc[..., 1]) <= cam.height_px / 2)
    return pc, vis, D


def simulate_cell(
    spec: CellSpec,
    motion: ThesisMotion,
    repetitions: int,
    rng: np.random.Generator,
    *,
    chunk_repetitions: int = 20,
) -> CellResult:
    """Run ``repetitions`` noisy passes over the motion series for one cell.

    Parameters
    ----------
    spec : CellSpec
    motion : ThesisMotion
    repetitions : int
        Passes over the series (500 in the thesis).
    rng : numpy.random.Generator
        Source of the eq. 4.1 noise.
    chunk_repetitions : int
        Passes estimated per vectorised batch (memory/speed trade-off only;
        the result does not depend on it for a given rng... except through the
        order of draws, so keep it fixed for reproducibility).
    """
    cam = thesis_camera(spec.resolution)
    pc, vis, D = clean_projection(spec, motion)
    S = len(motion)
    truth = np.stack([motion.roll_deg, motion.pitch_deg, motion.yaw_deg, D], axis=1)
    clean = estimate_thesis_batch(pc, vis, cam.fx, cam.fy, 10.0)
    n_q = 4
    mx = np.zeros(n_q)
    s1 = np.zeros(n_q)
    s2 = np.zeros(n_q)
    n_ok = 0
    rms_all: list[FloatArray] = []
    yz2_err: list[FloatArray] = []
    yz2_sign_hits = 0
    yz2_n = 0
    fail_counts = np.zeros(len(Failure), dtype=np.int64)
    done = 0
    while done < repetitions:
        r = min(chunk_repetitions, repetitions - done)
        noisy = thesis_uniform(np.broadcast_to(pc, (r,) + pc.shape), spec.noise_px,
                               cam.width_px, cam.height_px, rng)
        m = np.broadcast_to(vis, (r,) + vis.shape).reshape(r * S, -1)
        res = estimate_thesis_batch(noisy.reshape(r * S, -1, 2), m, cam.fx, cam.fy, 10.0)
        d2 = np.sum((noisy - pc) ** 2, axis=-1).reshape(r * S, -1)
        rms_all.append(np.sqrt(np.sum(np.where(m, d2, 0.0), axis=1) / np.maximum(m.sum(axis=1), 1)))
        t = np.tile(truth, (r, 1))
        est = np.stack([res.roll_deg, res.pitch_deg, res.yaw_deg, res.height], axis=1)
        err = est - t
        err[:, 2] = (err[:, 2] + 180.0) % 360.0 - 180.0
        ok = res.ok
        e = err[ok]
        if e.size:
            mx = np.maximum(mx, np.abs(e).max(axis=0))
            s1 += e.sum(axis=0)
            s2 += (e * e).sum(axis=0)
        n_ok += int(ok.sum())
        fail_counts += np.bincount(res.failure, minlength=len(Failure))
        yz_clean = np.tile(clean.yz2, r)
        both = ok & np.isfinite(yz_clean)
        yz2_err.append(res.yz2[both] - yz_clean[both])
        yz2_sign_hits += int(np.sum(np.sign(res.yz2[both]) == np.sign(yz_clean[both])))
        yz2_n += int(both.sum())
        done += r
    n = max(n_ok, 1)
    mean = s1 / n
    sigma = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0) * n / max(n - 1, 1))
    rms = np.concatenate(rms_all)
    ye = np.concatenate(yz2_err) if yz2_err else np.zeros(0)
    ys = float(np.std(ye)) if ye.size else float("nan")
    within = float(np.mean(np.abs(ye) <= ys) * 100.0) if ye.size else float("nan")
    failures = {Failure(i).name.lower(): int(c) for i, c in enumerate(fail_counts) if i and c}
    return CellResult(
        spec=spec,
        max_abs=mx,
        mean=mean,
        sigma=sigma,
        rms_mean_px=float(rms.mean()),
        rms_sigma_px=float(rms.std(ddof=1)) if rms.size > 1 else 0.0,
        yz2_within_sigma_pct=within,
        yz2_sign_pct=float(yz2_sign_hits / max(yz2_n, 1) * 100.0),
        n_images=repetitions * S,
        n_ok=n_ok,
        failures=failures,
    )
