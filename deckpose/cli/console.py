"""What a command prints on stdout, and what ``-q/--quiet`` leaves of it.

Without ``-q`` a command prints its summaries and stage lines. With ``-q`` it prints
errors only (on stderr, one line), plus what the user asked for: the data that is the
command's output (``deckpose crb``'s bounds, ``deckpose detect --list``'s names) or, for a
command that writes files, the path of its main output, bare on one line (so that
``out=$(deckpose render -q CONFIG RUN)`` holds the path). ``-q`` also turns the progress
bars off and logs errors only (:func:`~deckpose.cli.common_options.configure_logging`).
"""

from __future__ import annotations

import argparse
import os

__all__ = ["is_quiet", "say", "wrote"]


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
