#!/usr/bin/env bash
# Run the test suite in the local virtual environment (created if needed).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/bootstrap.sh
# lint first (the project's ruff config in pyproject.toml; a finding fails the run)
.venv/bin/ruff check --quiet . || { echo "[deckpose] ruff found the problems above; fix them (ruff check --fix .)" >&2; exit 1; }
# type check the library code (pyright, through a link tree: scripts/typecheck.sh); pyright needs node
if command -v node >/dev/null 2>&1; then
  echo "[deckpose] type-checking the library code (pyright, about a minute)"
  ./scripts/typecheck.sh >/dev/null
else
  echo "[deckpose] node (Node.js) not found: skipping the pyright type check (scripts/typecheck.sh)" >&2
fi
# one pytest worker per core, up to 4 (pytest-xdist; a module's tests stay on one worker, so its
# module-scoped fixtures are built once); DECKPOSE_TEST_WORKERS=0 runs them in this process
workers="${DECKPOSE_TEST_WORKERS:-$(.venv/bin/python -c 'import os; print(min(4, len(os.sched_getaffinity(0))))')}"
if [ "$workers" -gt 1 ] && .venv/bin/python -c "import xdist" 2>/dev/null; then
  exec .venv/bin/python -m pytest -n "$workers" --dist loadscope "$@"
fi
exec .venv/bin/python -m pytest "$@"
