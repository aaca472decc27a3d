"""Building the CLI's parser imports none of the heavy libraries that only some commands use.

Every command, even ``deckpose --help``, builds the whole parser. scipy.stats (the landing
window), scipy.signal (AR(2) sea noise) and scipy.optimize (the sea prior fit) used to be
imported by it, about 1 s of CPU on this machine before any work.
"""

from __future__ import annotations

import json
import subprocess
import sys


def test_the_parser_does_not_import_scipy_stats_signal_or_optimize() -> None:
    code = ("import sys, json; from deckpose.cli import build_parser; build_parser(); "
            "print(json.dumps([m for m in ('scipy.stats', 'scipy.signal', 'scipy.optimize') if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []
