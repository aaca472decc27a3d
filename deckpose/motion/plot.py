"""Plot a motion series: each channel over time beside its power spectral density."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from deckpose.atomic_io import atomic_path
from deckpose.errors import ConfigError, InputDataError
from deckpose.motion.series import MotionSeries

FloatArray = NDArray[np.float64]

#: Image formats a plot is written in, told by the file's suffix.
PLOT_FORMATS = ("png", "jpg", "pdf", "svg", "tiff")

#: (attribute, label, plotted unit, scale to plotted unit)
_CHANNELS = (
    ("roll_rad", "roll", "deg", float(np.degrees(1.0))),
    ("pitch_rad", "pitch", "deg", float(np.degrees(1.0))),
    ("yaw_rad", "yaw", "deg", float(np.degrees(1.0))),
    ("heave_m", "heave", "m", 1.0),
    ("surge_m", "surge", "m", 1.0),
    ("sway_m", "sway", "m", 1.0),
)


def channel_psd(t_s: FloatArray, x: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Welch one-sided PSD of a uniformly sampled channel, in angular frequency.

    Parameters
    ----------
    t_s : (T,) array of float
        Uniformly spaced times, seconds.
    x : (T,) array of float

    Returns
    -------
    omega_rad_s : (F,) array of float
    psd : (F,) array of float
        Unit^2 s / rad; ``sum(psd) * d_omega`` is the variance.
    """
    if t_s.size < 8:
        raise InputDataError(f"need at least 8 samples for a spectrum, got {t_s.size}")
    dt = float(np.median(np.diff(t_s)))
    if not np.allclose(np.diff(t_s), dt, rtol=1e-6, atol=1e-9):
        raise InputDataError("spectra need uniformly sampled times; resample the series first")
    # Segments of about a quarter of the series (at most ~14 min): a smooth yet resolved estimate.
    nper = int(min(t_s.size, max(64, t_s.size // 4), round(819.2 / dt)))
    f_hz, p = signal.welch(x - np.mean(x), fs=1.0 / dt, nperseg=nper)
    return 2.0 * np.pi * f_hz, p / (2.0 * np.pi)


def plot_series(series: MotionSeries, path: str | os.PathLike[str], *, title: str = "",
                max_omega_rad_s: float = 2.0, dpi: int = 80) -> Path:
    """Write a figure with each channel over time (left) and its spectrum (right).

    The format follows the file's suffix (:data:`PLOT_FORMATS`); another suffix is a
    :class:`~deckpose.errors.ConfigError`.

    Channels that are identically zero (e.g. surge and sway of a file without
    them) are left out. The file is written atomically.

    Parameters
    ----------
    series : MotionSeries
    path : path-like
        Output ``.png``.
    title : str
    max_omega_rad_s : float
        Upper limit of the spectrum axes, rad/s.
    dpi : int

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    chans = [c for c in _CHANNELS if np.any(getattr(series, c[0]) != 0)] or list(_CHANNELS[:1])
    fig = Figure(figsize=(10, 1.6 * len(chans) + 0.6), dpi=dpi)
    axes = fig.subplots(len(chans), 2, squeeze=False, gridspec_kw={"width_ratios": [2.2, 1]})
    uniform = len(series) >= 8 and np.allclose(np.diff(series.t_s), series.t_s[1] - series.t_s[0],
                                               rtol=1e-6, atol=1e-9)
    for row, (name, label, unit, scale) in enumerate(chans):
        x = getattr(series, name) * scale
        ax_t, ax_f = axes[row]
        ax_t.plot(series.t_s, x, lw=0.7)
        ax_t.set_ylabel(f"{label} [{unit}]")
        ax_t.grid(alpha=0.3)
        if uniform:
            w, p = channel_psd(series.t_s, x)
            keep = w <= max_omega_rad_s
            ax_f.plot(w[keep], p[keep], lw=0.9)
        else:
            ax_f.text(0.5, 0.5, "no spectrum:\nnon-uniform sampling", ha="center", va="center",
                      transform=ax_f.transAxes, fontsize=8)
        ax_f.grid(alpha=0.3)
        ax_f.set_ylabel(f"PSD [{unit}²·s/rad]", fontsize=8)
    axes[-1][0].set_xlabel("time [s]")
    axes[-1][1].set_xlabel("encounter frequency [rad/s]")
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    out = Path(path)
    fmt = out.suffix.lower().lstrip(".") or "png"
    fmt = {"jpeg": "jpg", "tif": "tiff"}.get(fmt, fmt)
    if fmt not in PLOT_FORMATS:
        raise ConfigError(
            f"cannot write a plot as {out.name}: name it .png, .jpg, .pdf, .svg or .tiff"
        )
    with atomic_path(out) as tmp:
        fig.savefig(tmp, format=fmt)
    return out
