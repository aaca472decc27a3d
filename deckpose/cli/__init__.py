"""The ``deckpose`` command line: one subcommand per job.

Each subcommand lives in its own module exposing ``register(subparsers)``; the
module keeps heavy imports inside its run function so ``--help`` stays fast.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
from collections.abc import Sequence

from deckpose.cli import exit_codes
from deckpose.cli.common_options import add_verbosity, configure_logging
from deckpose.errors import DeckposeError

#: Modules that register a subcommand, in the order ``--help`` lists them.
SUBCOMMAND_MODULES: tuple[str, ...] = (
    "deckpose.cli.demo_cmd",
    "deckpose.cli.pipeline_cmd",
    "deckpose.cli.motion_cmd",
    "deckpose.cli.render_cmd",
    "deckpose.cli.detect_cmd",
    "deckpose.cli.bench_detectors_cmd",
    "deckpose.cli.estimate_cmd",
    "deckpose.cli.track_cmd",
    "deckpose.cli.painted_ring_cmd",
    "deckpose.cli.crb_cmd",
    "deckpose.cli.evaluate_cmd",
    "deckpose.cli.export_cmd",
    "deckpose.cli.thesis_tables_cmd",
    "deckpose.cli.estimator_tables_cmd",
)


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every subcommand registered."""
    from deckpose import __version__

    parser = argparse.ArgumentParser(
        prog="deckpose",
        description=(
            "Render, detect and estimate a ship deck's attitude and position from "
            "monocular images of its beacons. Run 'deckpose COMMAND --help' for details."
        ),
    )
    parser.add_argument("--version", action="version", version=f"deckpose {__version__}")
    parser.add_argument(
        "--debug",
        action="store_true",
        help="show the Python traceback of an unexpected error (otherwise one line)",
    )
    add_verbosity(parser)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(name).register(sub)
    for sp in sub.choices.values():  # -v/-q after the command too
        add_verbosity(sp, command=True)
    return parser


def os_error_line(exc: OSError) -> tuple[str, int]:
    """One line and an exit status for an error of the file system.

    A read-only folder or a missing permission is the user's to fix (status 2); a
    full disk stops the job (status 1), and every writer wrote atomically, so the
    same command resumes or redoes only what was not finished.
    """
    import errno

    name = f" {exc.filename}" if exc.filename else ""
    if exc.errno == errno.ENOSPC:
        return ((f"the disk is full (writing{name}); free some space and run the same command again "
                "(finished files are kept, none is left half-written)"), exit_codes.UNEXPECTED)
    if exc.errno in (errno.EROFS, errno.EACCES, errno.EPERM):
        return (f"cannot write{name}: {exc.strerror}; choose a folder you can write to (or make it writable)",
                exit_codes.USAGE)
    return ((f"{type(exc).__name__}: {exc.strerror or exc}{name} (run 'deckpose --debug ...' for the "
            "traceback)"), exit_codes.UNEXPECTED)


#: What the interrupted line says when the command names no way to resume (``resume_hint``).
RESUME_HINT = "finished files are kept whole; run the same command again to finish"


def interrupted_line(argv: Sequence[str], args: argparse.Namespace | None = None) -> str:
    """The one line a Ctrl-C prints: the command, and how to finish the job.

    ``args`` is ``None`` when the interrupt came before the command line was parsed (the
    command is then the first word of ``argv`` that is not an option).
    """
    command = getattr(args, "command", None) or next((a for a in argv if not a.startswith("-")), "")
    hint = getattr(args, "resume_hint", None) or RESUME_HINT
    return f"deckpose{' ' + command if command else ''}: interrupted; {hint}"


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the process is, so that it stops as a Ctrl-C does."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``deckpose`` console script; returns the exit code.

    A Ctrl-C anywhere (the commands' imports included) prints one line and returns
    :data:`~deckpose.cli.exit_codes.INTERRUPTED`; the stages' worker processes ignore it
    and are stopped by the stage (:mod:`deckpose.worker_pool`). A SIGTERM (``kill``,
    ``timeout``, a batch scheduler) is taken the same way and returns
    :data:`~deckpose.cli.exit_codes.TERMINATED`, where Python's default died at once,
    leaving the worker processes and their semaphores behind. The handler is installed
    only where SIGTERM has its default action, in the main thread, for the call.
    """
    words = list(sys.argv[1:] if argv is None else argv)
    parsed: list[argparse.Namespace] = []
    own_sigterm = (threading.current_thread() is threading.main_thread()
                   and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)
    if own_sigterm:
        signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        return _main(words, parsed)
    except KeyboardInterrupt as exc:
        print(interrupted_line(words, parsed[0] if parsed else None), file=sys.stderr)
        return exit_codes.TERMINATED if isinstance(exc, Terminated) else exit_codes.INTERRUPTED
    finally:
        if own_sigterm:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _main(argv: list[str], parsed: list[argparse.Namespace]) -> int:
    """:func:`main` but for Ctrl-C; the parsed arguments are appended to ``parsed``."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    parsed.append(args)
    if extra:  # said by the command's own parser, with its usage, not the top level's
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        own = subs[0].choices.get(getattr(args, "command", None) or "") if subs else None
        (own or parser).error(f"unrecognized arguments: {' '.join(extra)}")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    configure_logging(args)
    if getattr(args, "quiet", False) and hasattr(args, "no_progress"):
        args.no_progress = True  # -q: errors and the result only (deckpose.cli.console), no bars
    try:
        return int(args.func(args) or 0)
    except DeckposeError as exc:
        text = " ".join(str(exc).split())  # one line, however the message was built
        if len(text) > 1000:
            text = text[:1000] + " ..."
        print(f"deckpose {args.command}: error: {text}", file=sys.stderr)
        return exit_codes.USAGE
    except BrokenPipeError:
        # the reader of our output went away (``deckpose ... | head``): stop quietly, as a Unix
        # tool does, and keep Python from complaining when it flushes stdout at exit
        import os

        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # a stdout without a file descriptor
            pass
        return exit_codes.BROKEN_PIPE
    except OSError as exc:
        if getattr(args, "debug", False):
            raise
        line, code = os_error_line(exc)
        print(f"deckpose {args.command}: error: {line}", file=sys.stderr)
        return code
    except Exception as exc:
        if getattr(args, "debug", False):
            raise
        text = " ".join(str(exc).split())
        if len(text) > 300:
            text = text[:300] + " ..."
        print(f"deckpose {args.command}: unexpected error: {type(exc).__name__}: {text} "
              "(run 'deckpose --debug ...' for the traceback)", file=sys.stderr)
        return exit_codes.UNEXPECTED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
