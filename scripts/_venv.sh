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
# The package itself, editable, so that `feed-axis-energy` and the node executables land in
# $VENV/bin (on PATH after `source .venv/bin/activate`). --use-pep517 makes pip build an
# editable wheel: pip writes the console scripts from its entry points into the venv's bin,
# and setup.cfg's [develop]/[install] script directories (the ament layout, lib/<package>, that
# colcon's `setup.py develop|install` reads for `ros2 run`) do not apply. Without it pip 23
# falls back to `setup.py develop` and the scripts end up in $VENV/lib/feed_axis_energy.
# Redone when the checkout moved or setup.py/setup.cfg changed (no dependencies, no network).
LINK="$VENV/.fae-editable"
LINK_WANT="$ROOT $(cat "$ROOT/setup.py" "$ROOT/setup.cfg" | sha256sum | cut -d' ' -f1) pep517"
if [ ! -f "$LINK" ] || [ "$(cat "$LINK")" != "$LINK_WANT" ]; then
    "$VENV/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
        --no-build-isolation --use-pep517 -e "$ROOT"
    # scripts an older set-up left in the ament layout (they would shadow nothing, but confuse)
    rm -rf "$VENV/lib/feed_axis_energy"
    echo "$LINK_WANT" > "$LINK"
fi
export PATH="$VENV/bin:$PATH"
export PYTHONPATH="$ROOT${PYTHONPATH:+:$PYTHONPATH}"
