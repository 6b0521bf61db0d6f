#!/usr/bin/env bash
# Set up if needed, then start fluorogui (desktop app, or the CLI with a sub-command).
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO_ROOT/packaging/setup.sh"
APP="$REPO_ROOT/.venv/bin/fluorogui"

# Same rule as fluorogui/__main__.py: no arguments, one project file or one folder (to
# import) opens the window; anything else is a command-line sub-command.
opens_window=false
if [ $# -eq 0 ]; then
  opens_window=true
elif [ $# -eq 1 ] && [[ "$1" != -* ]] && { [[ "${1,,}" == *.fluoro ]] || [ -f "$1" ] || [ -d "$1" ]; }; then
  opens_window=true
fi

if $opens_window && [ -z "${DISPLAY:-}" ] && [ -z "${WAYLAND_DISPLAY:-}" ]; then
  if command -v xvfb-run >/dev/null 2>&1; then
    echo "run: no display (DISPLAY and WAYLAND_DISPLAY unset): running under xvfb-run" >&2
    exec xvfb-run -a "$APP" "$@"
  fi
  echo "run: no display and no xvfb-run; the desktop app cannot open a window" >&2
fi
exec "$APP" "$@"
