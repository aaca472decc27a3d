#!/usr/bin/env bash
# Run the test suite in the local virtual environment (created if needed).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/bootstrap.sh
# lint first (the project's ruff config in pyproject.toml; a finding fails the run)
.venv/bin/ruff check --quiet . || { echo "[deckpose] ruff found the problems above; fix them (ruff check --fix .)" >&2; exit 1; }
exec .venv/bin/python -m pytest "$@"
