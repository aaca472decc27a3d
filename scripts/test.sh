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
exec .venv/bin/python -m pytest "$@"
