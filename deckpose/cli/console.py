"""What a command prints on stdout, and what ``-q/--quiet`` leaves of it.

Without ``-q`` a command prints its summaries and stage lines. With ``-q`` it prints
errors only (on stderr, one line), plus what the user asked for: the data that is the
command's output (``deckpose crb``'s bounds, ``deckpose detect --list``'s names) or, for a
command that writes files, the path of its main output, bare on one line (so that
``out=$(deckpose render -q CONFIG RUN)`` holds the path). ``-q`` also turns the progress
bars off and logs errors only (:func:`~deckpose.cli.common_options.configure_logging`).
Frames that failed are errors when they fail the command (a non-zero exit status, as with
``--strict``): then ``-q`` prints them too, on stderr (:func:`failures`).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterable

__all__ = ["failures", "is_quiet", "say", "wrote"]


def is_quiet(args: argparse.Namespace) -> bool:
    """Whether ``-q/--quiet`` was given (before or after the command)."""
    return bool(getattr(args, "quiet", False))


def say(args: argparse.Namespace, text: str) -> None:
    """Print a summary or status line, unless quiet."""
    if not is_quiet(args):
        print(text, flush=True)


def wrote(args: argparse.Namespace, path: str | os.PathLike[str], text: str) -> None:
    """The command's main output file: ``text`` (which names it), or with ``-q`` the bare path."""
    print(os.fspath(path) if is_quiet(args) else text, flush=True)


def failures(args: argparse.Namespace, lines: Iterable[str], *, failing: bool) -> None:
    """Lines naming the frames that failed and why: printed as a summary, or with ``-q`` on
    stderr when they fail the command (``failing``: its exit status is not 0)."""
    if not is_quiet(args):
        for line in lines:
            print(line, flush=True)
    elif failing:
        for line in lines:
            print(line.strip(), file=sys.stderr, flush=True)
