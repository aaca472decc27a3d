#!/usr/bin/env bash
# Run the test suite in the local virtual environment (created if needed).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/bootstrap.sh
exec .venv/bin/python -m pytest "$@"
