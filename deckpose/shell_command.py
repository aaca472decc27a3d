"""The ``deckpose`` command lines that messages suggest, each word quoted for a POSIX shell.

A hint such as ``make it with: deckpose detect RUN --detector cog`` is meant to be copied
into a shell, so a path with a space or a quote in it must come out quoted
(``deckpose detect 'my runs/a' --detector cog``). Every message that names a command with a
path builds it here; words that need no quoting (names, options, placeholders such as
``CONFIG.yaml``) are printed as they are.
"""

from __future__ import annotations

import os
import shlex

__all__ = ["deckpose_command"]


def deckpose_command(*words: str | os.PathLike[str]) -> str:
    """``deckpose`` followed by ``words``, each quoted with :func:`shlex.quote` where a shell needs it.

    Parameters
    ----------
    *words : str or path-like
        The command's words after ``deckpose``: the subcommand, paths, options, values.

    Returns
    -------
    str
        One line, e.g. ``deckpose render CONFIG.yaml 'runs/my run'``.
    """
    return " ".join(shlex.quote(os.fspath(w)) for w in ("deckpose", *words))
