"""The metadata records and attachments of a run's MCAP log.

Metadata (string key-value pairs): ``deckpose.run`` (dataset name, seed, format, the command
line as JSON), ``deckpose.config`` (the resolved render config and the deck layout, JSON),
``deckpose.versions`` (the manifest's package versions, plus the log writer's), and
``deckpose.time`` (the capture epoch of the log times and the rule that maps ``stamp_ns`` to
them). Attachments: each camera's ``camera_info`` YAML (``cameras/<name>.yaml``), the manifest
and, when it exists, the report (``report/report.md``).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from deckpose import run_folder as rl

if TYPE_CHECKING:
    from deckpose.evaluate.mcap_log import McapLog

__all__ = ["write_records"]


def _versions(manifest: dict[str, Any]) -> dict[str, str]:
    import importlib.metadata

    from deckpose import __version__

    out = {str(k): str(v) for k, v in dict(manifest.get("versions") or {}).items()}
    out["deckpose (log)"] = __version__
    for pkg in ("mcap", "foxglove-schemas-protobuf"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            pass
    return out


def write_records(log: McapLog, run: rl.RunPaths, manifest: dict[str, Any], cameras: list[str],
                   command: Sequence[str], epoch: tuple[int, str], start_ns: int) -> None:
    """Write the log's metadata records and attachments.

    Parameters
    ----------
    log : McapLog
        The open log.
    run : RunPaths
        The run (its camera files, manifest and report are attached).
    manifest : dict
        The run's manifest (name, seed, format, config, layout, versions).
    cameras : list of str
        Names of the cameras whose ``camera_info`` files are attached.
    command : sequence of str
        The command line that made the log.
    epoch : (int, str)
        The capture epoch of the log times, integer nanoseconds, and where it came from
        (``"stamps"``, ``"manifest"`` or ``"default"``).
    start_ns : int
        The attachments' create and log time, integer nanoseconds (the log's first time).
    """
    log.metadata("deckpose.run", {"name": str(manifest.get("name", "")), "seed": str(manifest.get("seed", "")),
                                  "dataset_format": str(manifest.get("format", "")),
                                  "command": json.dumps(list(command))})
    log.metadata("deckpose.config", {"config": json.dumps(manifest.get("config") or {}, sort_keys=True),
                                     "layout": json.dumps(manifest.get("layout") or {}, sort_keys=True)})
    log.metadata("deckpose.versions", _versions(manifest))
    epoch_ns, source = epoch
    log.metadata("deckpose.time", {
        "capture_epoch_ns": str(epoch_ns), "capture_epoch_source": source,
        "rule": "stamp_ns is a capture time: log time = stamp_ns" if source == "stamps" else
                "stamp_ns is motion time: log time = capture_epoch_ns + the replay's offset + "
                "(stamp_ns - the replay's first stamp_ns); replays (camera, height, lighting) one second apart"})
    for name in cameras:
        path = run.camera_file(name)
        if path.is_file():
            log.attachment(rl.camera_relpath(name), "application/yaml", path.read_bytes(), start_ns)
    if run.manifest.is_file():
        log.attachment(run.manifest.name, "application/json", run.manifest.read_bytes(), start_ns)
    report = run.report_dir / "report.md"
    if report.is_file():
        log.attachment(report.relative_to(run.root).as_posix(), "text/markdown", report.read_bytes(), start_ns)
