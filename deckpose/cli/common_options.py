"""Options that several commands share, spelled and defaulted once.

* ``-o/--output``: where a command writes;
* ``--workers N``: worker processes, by default one per CPU core on every command;
* ``--scheduler ADDRESS``: a Dask scheduler whose workers run the command's tasks instead;
* ``--no-progress``: no progress bars (they are off anyway when the output is not a
  terminal: tqdm's ``disable=None``);
* ``-v/--verbose`` and ``-q/--quiet`` (top level): the log level of the ``deckpose``
  loggers (warnings by default, ``-v`` info, ``-vv`` debug, ``-q`` errors only); ``-q``
  also leaves of stdout only what was asked for (:mod:`deckpose.cli.console`) and turns
  the progress bars off.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tqdm import tqdm


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows an option's default, unless it has none worth saying (``None``, ``False``) or its
    help already says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.default in (None, False, argparse.SUPPRESS) or "default" in text:
            return text
        return super()._get_help_string(action) or text


def default_workers() -> int:
    """The ``--workers`` default: one per CPU core."""
    return os.cpu_count() or 1


def add_workers(p: argparse.ArgumentParser, what: str, *, zero: str | None = None) -> None:
    """``--workers N`` (default one per core); ``zero`` says what 0 means, if it is allowed."""
    extra = f"; 0 = {zero}" if zero else ""
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"{what} worker processes (default: one per CPU core, {default_workers()} "
                        f"here{extra})")


def workers(args: argparse.Namespace) -> int:
    """The ``--workers`` value, the default resolved; a negative one is refused (before any work)."""
    w = getattr(args, "workers", None)
    if w is not None and int(w) < 0:
        from deckpose.errors import ConfigError

        raise ConfigError(f"--workers must be >= 0, got {w}")
    return default_workers() if w is None else int(w)


def add_scheduler(p: argparse.ArgumentParser, what: str) -> None:
    """``--scheduler ADDRESS`` (a Dask scheduler; ``None`` when not given)."""
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help=f"Dask scheduler address (tcp://host:8786); {what} run on its workers")


def add_output(p: argparse.ArgumentParser, help: str, *, default: Path | None = None,
               required: bool = False, metavar: str = "PATH", dest: str = "output") -> None:
    """``-o/--output`` into ``args.<dest>`` (the old ``--out`` spelling still parses, unlisted)."""
    p.add_argument("-o", "--output", dest=dest, type=Path, default=default,
                   required=required, metavar=metavar,
                   help=help + (f" (default: {default})" if default is not None else ""))
    p.add_argument("--out", dest=dest, type=Path, help=argparse.SUPPRESS)


def add_progress(p: argparse.ArgumentParser) -> None:
    """``--no-progress``."""
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bars (they are off anyway when the output is not a terminal)")


def frame_bar(desc: str, *, enabled: bool, total: int | None = None, unit: str = "frame") -> tqdm:
    """A progress bar counting frames (or ``unit``), of ``total`` when known (off when not
    ``enabled`` or when not on a terminal)."""
    from tqdm import tqdm

    return tqdm(desc=desc, unit=unit, total=total, leave=False, disable=None if enabled else True)


def done_of_total(bar: tqdm) -> Callable[[int, int], None]:
    """A ``progress(done, total)`` callback that moves ``bar`` (for stages that count that way)."""
    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    return progress


def add_verbosity(p: argparse.ArgumentParser, *, command: bool = False) -> None:
    """``-v/--verbose`` (repeatable) and ``-q/--quiet``: on the top-level parser, and with
    ``command`` on a command's, where they are set only when given (so they do not undo
    the top level's)."""
    p.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS if command else 0,
                   help="log more: -v what each stage does, -vv debugging detail")
    p.add_argument("-q", "--quiet", action="store_true",
                   default=argparse.SUPPRESS if command else False,
                   help="quiet: errors only, plus the command's result (its output's path, or the data "
                        "asked for); no summaries or progress bars")


def configure_logging(args: Any) -> None:
    """Set the ``deckpose`` loggers' level from ``-v``/``-q`` (stderr, one line a record)."""
    level = logging.ERROR if getattr(args, "quiet", False) else (
        logging.WARNING, logging.INFO, logging.DEBUG)[min(2, int(getattr(args, "verbose", 0) or 0))]
    log = logging.getLogger("deckpose")
    log.setLevel(level)
    ours = [h for h in log.handlers if getattr(h, "_deckpose", False)]
    if not ours:
        handler = logging.StreamHandler()
        handler.setFormatter(logging.Formatter("deckpose %(levelname)s %(name)s: %(message)s"))
        handler._deckpose = True  # type: ignore[attr-defined]
        log.addHandler(handler)
    for h in ours:  # a later call (another command in this process) writes to today's stderr
        if isinstance(h, logging.StreamHandler):
            h.stream = sys.stderr  # (not setStream: it flushes the old stream, which may be closed)
    log.propagate = False
