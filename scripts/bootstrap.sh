#!/usr/bin/env bash
# Create or refresh the local virtual environment (.venv) with deckpose and its
# dependencies, system libraries included. Safe to run again: it only does work
# when something is missing or pyproject.toml changed.
set -euo pipefail
cd "$(dirname "$0")/.."

# System libraries for headless rendering (Mesa EGL on the CPU, and OSMesa).
SYS_PKGS="libegl1 libegl-mesa0 libgl1-mesa-dri libosmesa6"
missing=""
for p in $SYS_PKGS; do
  dpkg -s "$p" >/dev/null 2>&1 || missing="$missing $p"
done
if [ -n "$missing" ]; then
  if [ "$(id -u)" = "0" ]; then
    echo "[deckpose] installing system packages:$missing"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq --no-install-recommends $missing >/dev/null
  elif command -v sudo >/dev/null 2>&1; then
    echo "[deckpose] installing system packages with sudo:$missing"
    sudo apt-get update -qq >/dev/null
    sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $missing >/dev/null
  else
    echo "[deckpose] WARNING: missing system packages:$missing" >&2
    echo "[deckpose] rendering needs them; install with: apt-get install$missing" >&2
  fi
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "[deckpose] creating .venv"
  "$PY" -m venv .venv
fi
stamp=.venv/.deckpose-stamp
want=$(cat pyproject.toml | sha256sum | cut -d' ' -f1)
if [ ! -f "$stamp" ] || [ "$(cat "$stamp")" != "$want" ] || ! .venv/bin/python -c "import deckpose" 2>/dev/null; then
  echo "[deckpose] installing deckpose and its dependencies into .venv (about a minute; log in .venv/install.log)"
  .venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
  # one line per package as pip collects it, so a long install shows progress
  set +e
  .venv/bin/python -m pip install --progress-bar off -e ".[test,cluster,peers,video]" 2>&1 \
    | tee .venv/install.log \
    | { grep --line-buffered -E '^(Collecting|Successfully installed)' \
        | sed -u -e 's/^Collecting /[deckpose]   collecting /' \
                 -e 's/^Successfully installed.*/[deckpose]   installed/'; true; }
  rc=${PIPESTATUS[0]}
  set -e
  if [ "$rc" -ne 0 ]; then
    cat .venv/install.log >&2
    echo "[deckpose] pip install failed (log above, also in .venv/install.log)" >&2
    exit 1
  fi
  echo "$want" > "$stamp"
fi
