#!/usr/bin/env bash
# Set up if needed, then start fluorogui (desktop app, or the CLI with a sub-command).
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO_ROOT/packaging/setup.sh"
if [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ]; then
  if command -v xvfb-run >/dev/null 2>&1; then
    echo "run: no display (DISPLAY and WAYLAND_DISPLAY unset): running under xvfb-run" >&2
    exec xvfb-run -a "$REPO_ROOT/.venv/bin/fluorogui" "$@"
  fi
  echo "run: no display and no xvfb-run; the desktop app will not be able to open a window" >&2
fi
exec "$REPO_ROOT/.venv/bin/fluorogui" "$@"
