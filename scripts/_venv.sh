#!/usr/bin/env bash
# Create or refresh the project's virtual environment from the pinned requirements.
# Sourced by scripts/demo and scripts/test; re-installs only when a requirements file changed.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="${FAE_VENV:-$ROOT/.venv}"
PY="${PYTHON:-python3}"
if [ ! -x "$VENV/bin/python" ]; then
    echo "[setup] creating virtual environment in $VENV" >&2
    "$PY" -m venv "$VENV"
fi
STAMP="$VENV/.fae-requirements.sha256"
WANT="$(cat "$ROOT/requirements.txt" "$ROOT/requirements-dev.txt" "$ROOT/constraints.txt" | sha256sum | cut -d' ' -f1)"
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$WANT" ]; then
    echo "[setup] installing pinned requirements (first run takes a minute)" >&2
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check \
        -r "$ROOT/requirements-dev.txt" -c "$ROOT/constraints.txt"
    echo "$WANT" > "$STAMP"
fi
# The package itself, editable, so `feed-axis-energy` and the node executables are on PATH.
# Redone when the checkout moved or setup.py changed (cheap: no dependencies, no network).
LINK="$VENV/.fae-editable"
LINK_WANT="$ROOT $(sha256sum "$ROOT/setup.py" | cut -d' ' -f1)"
if [ ! -f "$LINK" ] || [ "$(cat "$LINK")" != "$LINK_WANT" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
        --no-build-isolation -e "$ROOT"
    echo "$LINK_WANT" > "$LINK"
fi
export PATH="$VENV/bin:$PATH"
export PYTHONPATH="$ROOT${PYTHONPATH:+:$PYTHONPATH}"
