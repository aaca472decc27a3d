"""The report's figures: error against resolution and height, error distributions, centroid
error against spot size, and example frames with a native-pixel inset.

Each function draws one PNG, written atomically; :func:`deckpose.evaluate.report.write_report`
calls them and writes the Markdown around them.
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
import pandas as pd
from matplotlib.lines import Line2D

from deckpose import run_folder as rl
from deckpose.atomic_io import atomic_open
from deckpose.errors import InputDataError
from deckpose.image_store import decode_image

__all__ = ["example_frame", "plot_centroid_vs_size", "plot_distributions", "plot_error_vs_height",
           "plot_error_vs_resolution", "plot_track_errors"]

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

_QUANT = (("roll_err_deg", "roll [deg]"), ("pitch_err_deg", "pitch [deg]"),
          ("yaw_err_deg", "yaw [deg]"), ("height_err_m", "height [m]"))


def _pyplot():
    """matplotlib's pyplot on the Agg backend, chosen when a figure is drawn rather than on
    import (importing this module leaves the caller's backend alone)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _legend(ax: Axes, **kw) -> None:
    """A legend when the axes hold labelled artists (a run whose every estimate failed has none)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)
    else:
        ax.text(0.5, 0.5, "no finite values", transform=ax.transAxes, ha="center", va="center")


def _save(fig: Figure, path: Path, *, layout: bool = True) -> None:
    buf = io.BytesIO()
    if layout:
        fig.tight_layout()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    _pyplot().close(fig)
    with atomic_open(path, "wb") as fh:
        fh.write(buf.getvalue())


def plot_error_vs_resolution(table: pd.DataFrame, sizes_px: dict[str, tuple[int, int]], path: Path,
                             saturated: set[tuple[str, float]] = frozenset()) -> None:  # type: ignore[assignment]
    """Error sigma against megapixels: the question "which resolution?" answered first.

    One column per detector + estimator (so estimators that agree cannot hide each other),
    one row per quantity, one line per camera height (colour); each point's error bar is the
    standard error of its sigma (``sigma / sqrt(2 (n - 1))`` over its ``n`` frames, written
    beside it); the Cramér–Rao bound of the same frames dashed in the same colour; points
    whose beacons clip are drawn hollow.
    """
    plt = _pyplot()
    t = table.copy()
    t["megapixels"] = [sizes_px.get(str(c), (0, 0))[0] * sizes_px.get(str(c), (0, 0))[1] / 1e6
                       for c in t.camera]
    t = t[t.megapixels > 0]
    combos = sorted({(d, m) for d, m in zip(t.detector, t.method)})
    heights = sorted(t.table_height_m.unique())
    cmap = plt.get_cmap("viridis")
    colour = {h: cmap(i / max(1, len(heights) - 1) * 0.9) for i, h in enumerate(heights)}
    quantities = (("roll", "roll [deg]"), ("pitch", "pitch [deg]"), ("yaw", "yaw [deg]"), ("height", "height [m]"))
    fig, axes = plt.subplots(len(quantities), max(1, len(combos)),
                             figsize=(3.4 * max(1, len(combos)) + 1.5, 2.5 * len(quantities)),
                             sharex=True, sharey="row", squeeze=False)
    for col, (det, method) in enumerate(combos):
        sub = t[(t.detector == det) & (t.method == method)]
        for row, (q, label) in enumerate(quantities):
            ax = axes[row, col]
            positive = False  # a log axis needs a positive value (one frame has a sigma of 0)
            for h in heights:
                g = sub[sub.table_height_m == h].sort_values("megapixels")
                if g.empty:
                    continue
                n = g.n_frames.to_numpy(float) * (1.0 - g.failure_rate.to_numpy(float))
                y = g[f"sigma_{q}"].to_numpy(float)
                positive |= bool(np.any(np.isfinite(y) & (y > 0)))
                se = y / np.sqrt(2.0 * np.maximum(n - 1.0, 1.0))
                ax.errorbar(g.megapixels, y, yerr=se, fmt="-", color=colour[h], lw=1.2, capsize=2,
                            label=f"{h:g} m")
                clip = np.array([(str(c), float(h)) in saturated for c in g.camera])
                ax.scatter(g.megapixels[~clip], y[~clip], s=18, color=colour[h], zorder=3)
                if clip.any():
                    ax.scatter(g.megapixels[clip], y[clip], s=30, facecolors="white",
                               edgecolors=colour[h], zorder=3, label="beacons clip" if h == heights[0] else None)
                if f"crb_{q}" in g and g[f"crb_{q}"].notna().any():
                    ax.plot(g.megapixels, g[f"crb_{q}"], "--", color=colour[h], alpha=0.7, lw=1)
                if row == 0:
                    for x_, y_, n_ in zip(g.megapixels, y, n):
                        ax.annotate(f"{n_:.0f}", (x_, y_), xytext=(3, 3), textcoords="offset points",
                                    fontsize=6, color=colour[h])
            ax.set_xscale("log")
            ax.set_yscale("log" if positive else "linear")
            mps = sorted(t.megapixels.unique())
            ax.set_xticks(mps, [f"{m:.2g}" for m in mps], minor=False)
            ax.set_xticks([], minor=True)
            ax.grid(alpha=0.3, which="both")
            if row == 0:
                ax.set_title(f"{det} + {method}", fontsize=9)
            if col == 0:
                ax.set_ylabel(f"sigma {label}")
            if row == len(quantities) - 1:
                ax.set_xlabel("megapixels")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    handles.append(Line2D([], [], ls="--", color="grey"))
    labels.append("Cramér–Rao bound")
    fig.suptitle("Error sigma against resolution (numbers: frames per point; bars: standard error "
                 "of sigma; hollow: beacon cores clip)", fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=7,
               title="camera height", title_fontsize=7, frameon=False)
    _save(fig, path, layout=False)


def plot_error_vs_height(table: pd.DataFrame, path: Path) -> None:
    """Error sigma vs height: one column per camera, one row per quantity, one colour per
    detector + estimator, the Cramér–Rao bound dashed in the same colour (log scale)."""
    plt = _pyplot()
    cams = sorted(table.camera.unique(), key=lambda c: (int(c.split("mp")[0]) if c.split("mp")[0].isdigit() else 0, c))
    combos = sorted({(d, m) for d, m in zip(table.detector, table.method)})
    colours = {c: plt.cm.tab10(i % 10) for i, c in enumerate(combos)}
    quantities = (("roll", "roll [deg]"), ("pitch", "pitch [deg]"), ("yaw", "yaw [deg]"), ("height", "height [m]"))
    fig, axes = plt.subplots(len(quantities), len(cams), figsize=(3.6 * len(cams) + 1, 2.6 * len(quantities)),
                             sharex=True, sharey="row", squeeze=False)
    for col, cam in enumerate(cams):
        for row, (q, label) in enumerate(quantities):
            ax = axes[row, col]
            for (det, method), g in table[table.camera == cam].groupby(["detector", "method"]):
                g = g.sort_values("table_height_m")
                colour = colours[(det, method)]
                ax.plot(g.table_height_m, g[f"sigma_{q}"], "o-", color=colour, ms=3, label=f"{det}+{method}")
                if f"crb_{q}" in g:
                    ax.plot(g.table_height_m, g[f"crb_{q}"], "--", color=colour, alpha=0.6)
            ax.set_yscale("log")
            ax.grid(alpha=0.3, which="both")
            if row == 0:
                ax.set_title(cam, fontsize=9)
            if col == 0:
                ax.set_ylabel(f"sigma {label}")
            if row == len(quantities) - 1:
                ax.set_xlabel("camera height [m]")
    _legend(axes[0, 0], fontsize=7)
    fig.suptitle("Error sigma vs height per resolution (dashed: Cramér–Rao bound of each estimator's frames)")
    _save(fig, path)


def plot_track_errors(errors: pd.DataFrame, due_errors: pd.DataFrame, predictions: pd.DataFrame, title: str,
                      path: Path) -> None:
    """A track's errors: against time (per frame, filtered, predicted) and the prediction's against its horizon.

    Parameters
    ----------
    errors : DataFrame
        :func:`deckpose.evaluate.track_errors.track_frame_errors`'s table.
    due_errors : DataFrame
        The roll error of the predictions due at each frame for one horizon: ``t_s``, ``roll_err_deg``
        (NaN where none is due); its horizon is in its ``attrs["horizon_s"]``.
    predictions : DataFrame
        :func:`deckpose.evaluate.track_errors.prediction_errors`'s table.
    """
    plt = _pyplot()
    fig, axes = plt.subplots(4, 1, figsize=(9, 10))
    t = errors["t_s"].to_numpy(float)
    axes[0].plot(t, errors["true_height_m"], "k-", lw=1)
    axes[0].set_ylabel("true height [m]")
    for ax, (q, label) in zip(axes[1:3], (("roll_err_deg", "roll error [deg]"), ("height_err_m", "height error [m]"))):
        ax.plot(t, errors[f"{q}_estimate"], ".", ms=3, color="0.55", label="per frame")
        ax.plot(t, errors[f"{q}_filtered"], "-", lw=1, color="C0", label="filtered")
        if q == "roll_err_deg" and len(due_errors):
            ax.plot(due_errors["t_s"], due_errors["roll_err_deg"], "-", lw=0.8, color="C3",
                    label=f"predicted {due_errors.attrs['horizon_s']:g} s earlier")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        _legend(ax, fontsize=7, loc="upper right")
    axes[2].set_xlabel("time [s]")
    ax = axes[3]
    for q, colour in (("roll_deg", "C0"), ("pitch_deg", "C1")):
        ax.plot(predictions["horizon_s"], predictions[f"{q}_rms_predicted"], "o-", color=colour,
                label=f"{q.split('_')[0]} predicted")
        ax.plot(predictions["horizon_s"], predictions[f"{q}_rms_held"], "s--", color=colour, alpha=0.6,
                label=f"{q.split('_')[0]} last estimate held")
    ax.set_xlabel("horizon [s]")
    ax.set_ylabel("RMS error [deg]")
    ax.grid(alpha=0.3)
    _legend(ax, fontsize=7)
    fig.suptitle(title)
    _save(fig, path)


def plot_distributions(errors: pd.DataFrame, path: Path) -> None:
    plt = _pyplot()
    fig, axes = plt.subplots(1, 4, figsize=(16, 3.5))
    for ax, (col, label) in zip(axes, _QUANT):
        for (det, method), g in errors.groupby(["detector", "method"]):
            v = g[col].to_numpy(float)
            v = v[np.isfinite(v)]
            if v.size:
                ax.hist(v, bins=40, histtype="step", label=f"{det}+{method}")
        ax.set_xlabel(f"error {label}")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("frames")
    _legend(axes[0], fontsize=7)
    _save(fig, path)


def plot_centroid_vs_size(ce_by_det: dict[str, pd.DataFrame], path: Path,
                          camera_of: dict[int, str] | None = None) -> None:
    """Centroid RMS error against apparent beacon radius, one line per detector and, with
    ``camera_of`` (frame id -> camera), per camera (line style)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.5, 4))
    styles = ("o-", "s--", "^:", "d-.")
    series = []
    for det, ce in ce_by_det.items():
        if camera_of is None:
            series.append((det, ce, "o-"))
            continue
        cams = ce.frame_id.map(camera_of)
        for k, cam in enumerate(sorted(cams.dropna().unique())):
            series.append((f"{det}, {cam}", ce[cams == cam], styles[k % len(styles)]))
    for det, ce, style in series:
        if ce.empty:
            continue
        bins = np.unique(np.quantile(ce.apparent_radius_px, np.linspace(0, 1, 11)))
        idx = np.clip(np.digitize(ce.apparent_radius_px, bins) - 1, 0, max(len(bins) - 2, 0))
        x, y = [], []
        for b in range(max(len(bins) - 1, 1)):
            sel = ce.err_px[idx == b]
            if len(sel):
                x.append(ce.apparent_radius_px[idx == b].mean())
                y.append(np.sqrt(np.mean(sel ** 2)))
        ax.plot(x, y, style, label=det)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("apparent beacon radius [px]")
    ax.set_ylabel("centroid RMS error [px]")
    ax.grid(alpha=0.3, which="both")
    _legend(ax, fontsize=8)
    _save(fig, path)


def example_frame(run: rl.RunPaths, frame: pd.Series, beacons: pd.DataFrame,
                  dets: dict[str, pd.DataFrame], path: Path, max_px: int = 1200) -> None:
    # A run rendered with --no-images keeps only the preview: shown in the frame's pixel
    # coordinates, without the native-pixel inset.
    kept = bool(frame["image"])
    image = run.root / frame["image"] if kept else run.preview(int(frame["frame_id"]))
    if not image.is_file():
        raise InputDataError(f"cannot read image {image}: no such file")
    img = decode_image(image.read_bytes(), str(image))
    if img.dtype == np.uint16:
        img = np.right_shift(img, 8).astype(np.uint8)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    cam = rl.read_cameras(run, [str(frame["camera"])])[str(frame["camera"])] if not kept else None
    H, W = (cam.height_px, cam.width_px) if cam is not None else img.shape[:2]
    b = beacons[(beacons.frame_id == frame.frame_id) & beacons.visible.astype(bool)]
    inset = None
    if len(b) and kept:
        # a zoomed inset around one beacon, at native pixels, where the sub-pixel offsets
        # between the truth and the detections show (cut before the frame is shrunk)
        c = b.iloc[0]
        half = max(4.0, 4.0 * float(c.get("apparent_radius_px", 2.0)))
        x0, x1 = int(max(0, c.u_px - half)), int(min(W, c.u_px + half + 1))
        y0, y1 = int(max(0, c.v_px - half)), int(min(H, c.v_px + half + 1))
        inset = (c, img[y0:y1, x0:x1].copy(), (x0, x1, y0, y1))
    # matplotlib gets at most max_px on the long side (a 64 MP frame handed over whole made
    # `deckpose report` peak at 4.6 GiB); the axes keep full-resolution pixel coordinates
    scale = min(1.0, max_px / max(img.shape[:2]))
    if scale < 1.0:
        img = cv2.resize(img, (max(1, round(W * scale)), max(1, round(H * scale))),
                         interpolation=cv2.INTER_AREA)
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 8 * H / W))
    ax.imshow(img, cmap="gray", interpolation="nearest", extent=(-0.5, W - 0.5, H - 0.5, -0.5))
    ax.scatter(b.u_px, b.v_px, s=80, facecolors="none", edgecolors="lime", label="truth")
    for det, d in dets.items():
        s = d[d.frame_id == frame.frame_id]
        ax.scatter(s.u_px, s.v_px, s=14, marker="x", label=det)
        for _, r in s.iterrows():
            ax.annotate(str(int(r.beacon_id)), (r.u_px, r.v_px), color="yellow", fontsize=7,
                        xytext=(4, -4), textcoords="offset points")
    if inset is not None:
        c, crop, (x0, x1, y0, y1) = inset
        ins = ax.inset_axes((0.02, 0.02, 0.3, 0.3))
        ins.imshow(crop, cmap="gray", interpolation="nearest", extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5))
        ins.scatter([c.u_px], [c.v_px], s=60, facecolors="none", edgecolors="lime")
        for det, d in dets.items():
            s = d[(d.frame_id == frame.frame_id) & (d.beacon_id == c.beacon_id)]
            ins.scatter(s.u_px, s.v_px, s=30, marker="x")
        ins.set_xlim(x0 - 0.5, x1 - 0.5)
        ins.set_ylim(y1 - 0.5, y0 - 0.5)
        ins.set_xticks([])
        ins.set_yticks([])
        ins.set_title(f"beacon {int(c.beacon_id)}, native pixels", fontsize=6, color="white")
    ax.set_title(f"frame {frame.frame_id}: {frame.camera}, {frame.camera_height_m:g} m, {frame.get('lighting', '')}"
                 + ("" if kept else " (preview: the frame was not kept)"))
    _legend(ax, fontsize=7, loc="lower right")
    ax.set_axis_off()
    _save(fig, path)
