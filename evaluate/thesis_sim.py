"""Monte Carlo of the thesis's chapter-4 experiment for one table cell.

The set-up is the one that reproduces Tables 4.2-4.15 (reference page, "How the
thesis tables were produced"): the thesis camera (75 deg focal angle, non-square
form) at one resolution; the 495-sample regular-wave motion series; camera
distance = table height + heave; beacons outside the image dropped; eq. 4.1-4.3
noise of N px; the faithful estimator; errors against the true thesis angles.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from deckpose.estimate.thesis_algorithm import Failure, thesis_algorithm
from numpy.typing import NDArray

from deckpose.camera import THESIS_RESOLUTIONS, CameraModel, PixelForm, from_focal_angle
from deckpose.errors import InputDataError
from deckpose.layout import thesis_layout
from deckpose.noise import thesis_uniform
from deckpose.projection import project_thesis_centred
from deckpose.records import Detections
from deckpose.rotation import R_from_thesis, thesis_from_zyx

if TYPE_CHECKING:
    from deckpose.estimate.registry import EstimateOptions

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


def thesis_camera(resolution: str) -> CameraModel:
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


@dataclass(frozen=True)
class BatchOutput:
    """What a batch estimator returns for the simulation; arrays of shape (F,).

    Angles are the thesis's convention (``R = Rx(roll) Ry(pitch) Rz(yaw)``), degrees,
    so they compare directly with the thesis's truth and tables.
    """

    roll_deg: FloatArray
    pitch_deg: FloatArray
    yaw_deg: FloatArray
    height: FloatArray
    ok: NDArray[np.bool_]
    failure: NDArray[np.object_]  # reason key per frame ("" when ok)
    yz2: FloatArray  # the thesis's Y''_z (NaN for other methods)


#: A batch estimator: centred points (F, N, 2), mask (F, N), camera -> BatchOutput.
BatchEstimator = Callable[[FloatArray, NDArray[np.bool_], CameraModel], BatchOutput]


def thesis_batch_estimator(points_c: FloatArray, mask: NDArray[np.bool_], camera: CameraModel) -> BatchOutput:
    """The vectorised faithful thesis estimator as a :data:`BatchEstimator`."""
    res = thesis_algorithm(points_c, mask, camera.fx, camera.fy, 10.0)
    names = np.array([""] + [f.name.lower() for f in list(Failure)[1:]], dtype=object)
    return BatchOutput(res.roll_deg, res.pitch_deg, res.yaw_deg, res.height, res.ok, names[res.failure], res.yz2)


def registry_batch_estimator(method: str, options: EstimateOptions | None = None) -> BatchEstimator:
    """Any registered estimator as a :data:`BatchEstimator` (through :func:`estimate_batch`).

    Beacons keep their ring ids (row ``i`` of the points is beacon ``i``); the
    layout is the thesis's (no centre beacon).
    """
    from deckpose.estimate import registry
    from deckpose.estimate.batch import estimate_batch

    registry.get(method)  # fail early on an unknown name
    opts = options or registry.EstimateOptions()
    layout = thesis_layout()

    def run(points_c: FloatArray, mask: NDArray[np.bool_], camera: CameraModel) -> BatchOutput:
        F = points_c.shape[0]
        out = np.full((F, 4), np.nan)
        ok = np.zeros(F, dtype=bool)
        failure = np.full(F, "", dtype=object)
        dets = []
        for f in range(F):
            ids = np.flatnonzero(mask[f])
            uv = np.column_stack([points_c[f, ids, 0] + camera.cx, camera.cy - points_c[f, ids, 1]])
            dets.append(Detections(uv, ids))
        for f, est in enumerate(estimate_batch(method, dets, camera, layout, opts)):
            if not est.ok:
                failure[f] = est.reason
                continue
            r, p, y = thesis_from_zyx(est.roll_rad, est.pitch_rad, est.yaw_rad)
            out[f] = np.degrees([r, p, y]).tolist() + [est.height_m]
            ok[f] = True
        return BatchOutput(out[:, 0], out[:, 1], out[:, 2], out[:, 3], ok, failure, np.full(F, np.nan))

    return run


def simulate_cell(
    spec: CellSpec,
    motion: ThesisMotion,
    repetitions: int,
    rng: np.random.Generator,
    *,
    estimator: BatchEstimator = thesis_batch_estimator,
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
    estimator : BatchEstimator
        The estimator under test (default: the vectorised thesis estimator).
    chunk_repetitions : int
        Passes drawn and estimated per batch. It fixes the order of the random
        draws, so keep it fixed for reproducible numbers.
    """
    cam = thesis_camera(spec.resolution)
    pc, vis, D = clean_projection(spec, motion)
    S = len(motion)
    truth = np.stack([motion.roll_deg, motion.pitch_deg, motion.yaw_deg, D], axis=1)
    clean = estimator(pc, vis, cam)
    n_q = 4
    mx = np.zeros(n_q)
    s1 = np.zeros(n_q)
    s2 = np.zeros(n_q)
    n_ok = 0
    rms_all: list[FloatArray] = []
    yz2_err: list[FloatArray] = []
    yz2_sign_hits = 0
    yz2_n = 0
    fail_counts: dict[str, int] = {}
    done = 0
    while done < repetitions:
        r = min(chunk_repetitions, repetitions - done)
        noisy = thesis_uniform(np.broadcast_to(pc, (r,) + pc.shape), spec.noise_px,
                               cam.width_px, cam.height_px, rng)
        m = np.broadcast_to(vis, (r,) + vis.shape).reshape(r * S, -1)
        res = estimator(noisy.reshape(r * S, -1, 2), m, cam)
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
        for key in res.failure[~ok]:
            fail_counts[str(key)] = fail_counts.get(str(key), 0) + 1
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
    failures = dict(sorted(fail_counts.items()))
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
