#!/usr/bin/env bash
# Run deckpose's main job end to end on the embedded default configuration.
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/bootstrap.sh
exec .venv/bin/deckpose demo "$@"
