"""The exit status of every ``deckpose`` command, documented in the README.

* :data:`OK` (0): the job ran (some frames may have failed; each says why in its row);
* :data:`UNEXPECTED` (1): an unexpected error (a bug, a full disk): one line, or the
  traceback with ``deckpose --debug``;
* :data:`USAGE` (2): bad input or usage (a missing file, a bad option or config);
* :data:`NO_FRAME_OK` (3): the job ran but no frame succeeded;
* :data:`SOME_FAILED` (4): with ``--strict``, some frames failed;
* :data:`INTERRUPTED` (130, 128 + SIGINT): stopped by Ctrl-C (finished files kept; the same
  command resumes);
* :data:`BROKEN_PIPE` (141, 128 + SIGPIPE): the reader of the output went away
  (``deckpose ... | head``); nothing is printed;
* :data:`TERMINATED` (143, 128 + SIGTERM): stopped by SIGTERM (``kill``, ``timeout``, a
  scheduler), handled as a Ctrl-C: one line, finished files kept, the same command resumes.
"""

from __future__ import annotations

OK = 0
UNEXPECTED = 1
USAGE = 2
NO_FRAME_OK = 3
SOME_FAILED = 4
INTERRUPTED = 130
BROKEN_PIPE = 141
TERMINATED = 143


def frames_exit_code(n_frames: int, n_ok: int, *, strict: bool = False) -> int:
    """The status of a job over frames: :data:`NO_FRAME_OK` when frames ran and none
    succeeded, :data:`SOME_FAILED` when ``strict`` and any failed, else :data:`OK`."""
    if n_frames > 0 and n_ok == 0:
        return NO_FRAME_OK
    if strict and n_ok < n_frames:
        return SOME_FAILED
    return OK
