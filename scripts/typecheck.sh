#!/usr/bin/env bash
# Type-check the library code (deckpose, render, detect, estimate, evaluate) with pyright,
# using the settings in pyproject.toml's [tool.pyright]. Exits non-zero on any error.
#
# pyright cannot follow pyproject's package-dir mapping (render/ installs as deckpose.render,
# ...; the editable install is an import hook), so this lays the code out as installed, in a
# temporary tree of links (deckpose/ with render/ detect/ estimate/ evaluate/ inside it), runs
# pyright there and prints the errors with the repository's own paths.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
pyright=.venv/bin/pyright
[ -x "$pyright" ] || { echo "[deckpose] $pyright not found; run scripts/bootstrap.sh first" >&2; exit 1; }
command -v node >/dev/null 2>&1 || { echo "[deckpose] pyright needs node (Node.js), not found on PATH" >&2; exit 1; }

tree=$(mktemp -d)
trap 'rm -rf "$tree"' EXIT
cp -rs "$repo/deckpose" "$tree/deckpose"
for d in render detect estimate evaluate; do
  cp -rs "$repo/$d" "$tree/deckpose/$d"
done
find "$tree" -name __pycache__ -type d -prune -exec rm -rf {} +
# the config (paths in it are relative to it) and the environment it names
cp pyproject.toml "$tree/pyproject.toml"
ln -s "$repo/.venv" "$tree/.venv"

# pinned on purpose (pyproject's test extra): no "new pyright version" check, a PyPI request
export PYRIGHT_PYTHON_IGNORE_WARNINGS=1
set +e
out=$(cd "$tree" && "$repo/$pyright" -p pyproject.toml 2>&1)
rc=$?
set -e
for d in render detect estimate evaluate; do
  out=${out//"$tree/deckpose/$d/"/"$d/"}
done
out=${out//"$tree/deckpose/"/"deckpose/"}
out=${out//"$tree/"/}
if [ "$rc" -ne 0 ]; then
  printf '%s\n' "$out" >&2
  echo "[deckpose] pyright found the type errors above (paths are the repository's); fix them and run scripts/typecheck.sh again" >&2
  exit 1
fi
printf '%s\n' "$out" | tail -n 1
