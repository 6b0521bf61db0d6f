#!/usr/bin/env bash
# Set up if needed, then run the test suite (under Xvfb, Qt offscreen by default).
# Usage: bash packaging/test.sh [pytest args]
#   bash packaging/test.sh                  everything (what CI runs, through .ci/run)
#   bash packaging/test.sh -m "not slow"    the development loop: without the end-to-end
#                                           validations marked slow (pyproject.toml)
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO_ROOT/packaging/setup.sh"
cd "$REPO_ROOT"
export QT_QPA_PLATFORM="${QT_QPA_PLATFORM:-offscreen}"

# One pytest worker per core (pytest-xdist): on 2 cores the suite takes about half the
# time. FLUOROGUI_TEST_WORKERS=0 runs in one process (needed for -s / pdb).
workers="${FLUOROGUI_TEST_WORKERS:-auto}"
cmd=("$REPO_ROOT/.venv/bin/python" -m pytest -q)
if [ "$workers" != "0" ]; then
  cmd+=(-n "$workers")
fi
cmd+=("$@")
if command -v xvfb-run >/dev/null 2>&1; then
  cmd=(xvfb-run -a -s "-screen 0 1920x1080x24" "${cmd[@]}")
else
  echo "test: xvfb-run not found; tests that need a real display will fail or skip" >&2
fi

status=0
"${cmd[@]}" || status=$?
if [ "$status" -eq 5 ]; then
  echo "test: ERROR: pytest collected no tests" >&2
fi
exit "$status"
