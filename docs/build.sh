#!/usr/bin/env bash
# Build the documentation into docs/_build/html, warnings as errors, and check it:
#   1. set up (packaging/setup.sh: .venv with fluorogui; then the [docs] extra into it);
#   2. run the public API's doctests (quick ones, on the built-in demo);
#   3. sphinx-build -W (the command reference from the argparse parsers, the API reference
#      from the docstrings, the validation page from docs/validation/results.json);
#   4. docs/check_site.py: every sub-command and option of `fluorogui --help` is on the
#      built pages, and the API pages name Session, FrameResult and track.
# Needs no network beyond the package index (for the first set-up). Usage:
#     bash docs/build.sh                 # FLUOROGUI_VENV=DIR uses another environment
set -euo pipefail
DOCS="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO_ROOT="$(dirname "$DOCS")"
VENV="${FLUOROGUI_VENV:-$REPO_ROOT/.venv}"
say() { echo "docs: $*" >&2; }
t0=$SECONDS

if [ -z "${FLUOROGUI_VENV:-}" ]; then
  bash "$REPO_ROOT/packaging/setup.sh"
fi
PY="$VENV/bin/python"
[ -x "$PY" ] || { say "ERROR: no Python at $PY"; exit 1; }
if ! "$PY" -c "import sphinx, furo, sphinxarg, numpydoc, myst_parser" >/dev/null 2>&1; then
  if [ -n "${FLUOROGUI_VENV:-}" ]; then
    say "ERROR: $VENV lacks the documentation tools; install them with:"
    say "  $PY -m pip install 'sphinx>=7.3' 'furo>=2024.8.6' 'sphinx-argparse>=0.5' 'numpydoc>=1.8' 'myst-parser>=3'"
    exit 1
  fi
  say "installing the documentation tools into .venv (pip install -e .[test,docs])"
  log="$(mktemp)"
  if ! "$PY" -m pip install -q --disable-pip-version-check -e "$REPO_ROOT[test,docs]" >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    rm -f "$log"
    say "ERROR: pip install -e .[test,docs] failed (see above)"
    exit 1
  fi
  rm -f "$log"
fi

# The checked-out tree is what gets documented and doctested, whatever is installed.
export PYTHONPATH="$REPO_ROOT${PYTHONPATH:+:$PYTHONPATH}"
export QT_QPA_PLATFORM="${QT_QPA_PLATFORM:-offscreen}"
export FLUOROGUI_DATA_DIR="${FLUOROGUI_DATA_DIR:-$(mktemp -d -t fluorogui-docs-data.XXXXXX)}"

say "doctests of the public API"
cd "$REPO_ROOT"
PYTHONPATH="$DOCS:$PYTHONPATH" "$PY" -m pytest -q -p no:cacheprovider -p doctest_setup --doctest-modules --rootdir="$REPO_ROOT" \
  --confcutdir="$DOCS" -o addopts="" -o testpaths="" \
  fluorogui/__init__.py fluorogui/workflow/session/reader.py fluorogui/workflow/session/session.py \
  fluorogui/workflow/session/work.py fluorogui/workflow/session/edits.py fluorogui/workflow/session/knee.py \
  fluorogui/workflow/results.py fluorogui/workflow/settings.py fluorogui/core/search/find.py \
  fluorogui/core/matching/matcher.py fluorogui/core/matching/loop.py fluorogui/core/knee/kinematics.py

say "sphinx-build (warnings are errors)"
rm -rf "$DOCS/_build/html" "$DOCS/_build/doctrees"
"$PY" -m sphinx -W --keep-going -q -b html -d "$DOCS/_build/doctrees" "$DOCS" "$DOCS/_build/html"

"$PY" "$DOCS/check_site.py" "$DOCS/_build/html"
say "built $DOCS/_build/html in $((SECONDS - t0)) s"
