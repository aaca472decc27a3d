"""The capture time base of a dataset: frame stamps in nanoseconds since the Unix epoch.

A render job replays its motion series for every camera, height and lighting
(:func:`deckpose.render.plan.plan_frames` nests the motion samples innermost). On the
capture time base the replays are laid end to end from the job's capture epoch, one
second apart, each keeping its own sample spacing: every frame's ``stamp_ns`` is then
a distinct, increasing time that a log viewer shows as a date. One rule,
:func:`replay_starts_ns`, serves the renderer (which writes such stamps) and the log
(which lays out the motion-time stamps of older datasets the same way).
"""

from __future__ import annotations

from datetime import datetime, timezone
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from deckpose.errors import ConfigError, InputDataError

if TYPE_CHECKING:  # pandas is imported where used: every render config (and command) paid its import
    import pandas as pd

#: The default capture epoch, 2024-01-01T00:00:00Z, integer nanoseconds since the Unix epoch.
DEFAULT_CAPTURE_EPOCH = "2024-01-01T00:00:00Z"
DEFAULT_CAPTURE_EPOCH_NS = 1_704_067_200_000_000_000
#: Stamps at or after 2000-01-01T00:00:00Z (integer nanoseconds) count as capture times already.
EPOCH_FLOOR_NS = 946_684_800_000_000_000
#: The gap between two replays of the motion series on the capture time base.
REPLAY_GAP_NS = 1_000_000_000


def epoch_ns(text: str, where: str = "capture_epoch") -> int:
    """An ISO 8601 UTC time (``2024-01-01T00:00:00Z``) as integer nanoseconds since the Unix epoch.

    Raises
    ------
    ConfigError
        Not an ISO 8601 time with a time zone, or before 2000-01-01.
    """
    try:
        t = datetime.fromisoformat(str(text).replace("Z", "+00:00"))
    except ValueError:
        raise ConfigError(f"{where}: {text!r} is not an ISO 8601 time; write e.g. "
                          f"{DEFAULT_CAPTURE_EPOCH!r}") from None
    if t.tzinfo is None:
        raise ConfigError(f"{where}: {text!r} has no time zone; add Z for UTC (e.g. {DEFAULT_CAPTURE_EPOCH!r})")
    delta = t.astimezone(timezone.utc) - datetime(1970, 1, 1, tzinfo=timezone.utc)
    ns = (delta.days * 86_400 + delta.seconds) * 1_000_000_000 + delta.microseconds * 1_000
    if ns < EPOCH_FLOOR_NS:
        raise ConfigError(f"{where}: {text!r} is before 2000-01-01; a capture time is a date of this century")
    return ns


def replay_starts_ns(first_ns: NDArray[np.int64], last_ns: NDArray[np.int64], epoch: int) -> NDArray[np.int64]:
    """Where each replay starts on the capture time base.

    Parameters
    ----------
    first_ns, last_ns : (R,) arrays of int
        Motion time of each replay's first and last frame, nanoseconds, in replay order.
    epoch : int
        Capture time of the first replay's first frame, nanoseconds since the Unix epoch.

    Returns
    -------
    (R,) array of int
        ``epoch`` for the first replay; each next one :data:`REPLAY_GAP_NS` after the
        previous one's last frame.
    """
    span = np.asarray(last_ns, np.int64) - np.asarray(first_ns, np.int64)
    starts = np.empty(span.shape, np.int64)
    if span.size:
        starts[0] = epoch
        starts[1:] = epoch + np.cumsum(span[:-1] + REPLAY_GAP_NS)
    return starts


def log_stamps(frames: pd.DataFrame, epoch_ns: int = DEFAULT_CAPTURE_EPOCH_NS) -> pd.Series:
    """Log times, integer nanoseconds since the Unix epoch, one per frame.

    Parameters
    ----------
    frames : DataFrame
        The frames table (``frame_id``, ``camera``, ``camera_height_m``, ``stamp_ns``).
    epoch_ns : int
        Capture time of motion time 0, integer nanoseconds since the Unix epoch; used
        only when the stamps are motion time.

    Returns
    -------
    Series of int64, indexed like ``frames``
        ``stamp_ns`` itself where every stamp is a capture time already (at or after
        :data:`EPOCH_FLOOR_NS`). Otherwise the stamps are motion time, which a dataset
        replays for every camera, height and lighting (the render plan nests motion
        samples innermost): within each (camera, height) group, in frame-id order, a
        replay ends where ``stamp_ns`` stops increasing; replays are laid end to end
        from ``epoch_ns``, one second apart, each keeping its own stamp spacing, so
        the log times are distinct and increase with the frame order.
    """
    import pandas as pd

    s_all = frames["stamp_ns"].to_numpy(np.int64)
    if len(frames) and int(s_all.min()) >= EPOCH_FLOOR_NS:
        return pd.Series(s_all, index=frames.index, dtype=np.int64)
    order = frames.sort_values(["camera", "camera_height_m", "frame_id"], kind="stable")
    s = order["stamp_ns"].to_numpy(np.int64)
    cam = order["camera"].to_numpy()
    height = order["camera_height_m"].to_numpy()
    starts = np.ones(len(order), dtype=bool)
    starts[1:] = (s[1:] <= s[:-1]) | (cam[1:] != cam[:-1]) | (height[1:] != height[:-1])
    replay = np.cumsum(starts) - 1
    n_replays = int(replay.max()) + 1 if len(order) else 0
    first = np.array([s[replay == r].min() for r in range(n_replays)], np.int64)
    last = np.array([s[replay == r].max() for r in range(n_replays)], np.int64)
    begin = replay_starts_ns(first, last, int(epoch_ns))
    out = pd.Series(0, index=frames.index, dtype=np.int64)
    out.loc[order.index] = s - first[replay] + begin[replay]
    return out


def capture_epoch(manifest: dict[str, Any]) -> tuple[int, str]:
    """Capture time of motion time 0 (integer ns since the Unix epoch) and where it came from.

    The manifest's ``capture_epoch_ns`` when it has one (an int at or after
    :data:`EPOCH_FLOOR_NS`), else :data:`DEFAULT_CAPTURE_EPOCH_NS`.
    """
    value = manifest.get("capture_epoch_ns")
    if value is None:
        return DEFAULT_CAPTURE_EPOCH_NS, "default"
    if isinstance(value, bool) or not isinstance(value, int) or value < EPOCH_FLOOR_NS:
        raise InputDataError(f"manifest capture_epoch_ns must be integer nanoseconds since the Unix epoch, "
                             f"at or after 2000-01-01, got {value!r}")
    return value, "manifest"
