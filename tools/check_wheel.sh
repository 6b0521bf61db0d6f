#!/usr/bin/env bash
# Is fluorogui installable without the repository? Clone the committed tree, build a wheel
# from the clone, install it into a brand-new virtual environment (its dependencies come
# from the package index, so this takes minutes), then, in an empty folder far from any
# checkout, run `fluorogui --version`, `fluorogui demo` and `fluorogui track`, and check
# that the wheel carries LICENSE and py.typed. Too slow for the test suite; run it before a
# release:
#
#     bash tools/check_wheel.sh [WORK_DIR]      # WORK_DIR default: a new temporary folder
#
# Environment: PYTHON (default python3) makes the venv and builds the wheel.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PYTHON="${PYTHON:-python3}"
WORK="${1:-$(mktemp -d -t fluorogui-wheel.XXXXXX)}"
mkdir -p "$WORK"
WORK="$(cd "$WORK" && pwd)"
say() { echo "check_wheel: $*" >&2; }
t0=$SECONDS

say "cloning $REPO_ROOT (committed tree only) into $WORK/clone"
rm -rf "$WORK/clone" "$WORK/dist" "$WORK/venv" "$WORK/run"
git clone -q --no-hardlinks "$REPO_ROOT" "$WORK/clone"

say "building the wheel (isolated build: setuptools from the index)"
"$PYTHON" -m pip wheel -q --no-deps -w "$WORK/dist" "$WORK/clone"
wheel="$(ls "$WORK"/dist/fluorogui-*.whl)"
say "built $(basename "$wheel") ($(du -k "$wheel" | cut -f1) KiB)"
"$PYTHON" - "$wheel" <<'PY'
import sys, zipfile
names = zipfile.ZipFile(sys.argv[1]).namelist()
need = {"fluorogui/py.typed": "py.typed", "LICENSE": "the licence file"}
for suffix, what in need.items():
    if not any(n.endswith(suffix) for n in names):
        sys.exit(f"check_wheel: the wheel lacks {what} ({suffix})")
meta = next(n for n in names if n.endswith(".dist-info/METADATA"))
text = zipfile.ZipFile(sys.argv[1]).read(meta).decode()
for line in ("License-Expression: BSD-3-Clause", "Requires-Dist: pillow", "Requires-Dist: vtk"):
    if line not in text:
        sys.exit(f"check_wheel: METADATA lacks {line!r}")
entry = next(n for n in names if n.endswith(".dist-info/entry_points.txt"))
if "[gui_scripts]" not in zipfile.ZipFile(sys.argv[1]).read(entry).decode():
    sys.exit("check_wheel: no gui_scripts entry point")
print("check_wheel: the wheel has LICENSE, py.typed, the SPDX licence, Pillow, VTK and a GUI entry point",
      file=sys.stderr)
PY

say "a fresh virtual environment (no system site-packages), the wheel and its dependencies"
"$PYTHON" -m venv "$WORK/venv"
"$WORK/venv/bin/python" -m pip install -q --disable-pip-version-check "$wheel"

mkdir -p "$WORK/run"
cd "$WORK/run"
export FLUOROGUI_DATA_DIR="$WORK/run/data"   # the log file lands here, not in the user's home
app="$WORK/venv/bin/fluorogui"
say "in $PWD: fluorogui --version"
"$app" --version
say "fluorogui demo demo.fluoro"
"$app" demo demo.fluoro --frames 3
say "fluorogui track demo.fluoro --json"
status=0
"$app" track demo.fluoro --json >track.jsonl || status=$?
# 0: every frame matched; 3: some need review (a valid outcome, reported). Anything else fails.
if [ "$status" -ne 0 ] && [ "$status" -ne 3 ]; then
  say "FAILED: fluorogui track exited $status"
  exit 1
fi
"$WORK/venv/bin/python" - track.jsonl <<'PY'
import json, sys
rows = [json.loads(line) for line in open(sys.argv[1]) if line.strip()]
if not rows:
    sys.exit("check_wheel: track printed no results")
for r in rows:
    print(f"  frame {r['frame']} {r['component']:<8} {r['status']:<13} "
          f"objective {r['objective_mm']} mm {r['reason']}", file=sys.stderr)
PY
say "fluorogui bench --method fast --starts 1 (no data: the demo's components)"
"$app" bench --method fast --starts 1
if grep -rq "shared" "$WORK/run/data" 2>/dev/null; then
  say "note: the log mentions 'shared' (see $WORK/run/data)"
fi
say "OK in $((SECONDS - t0)) s: the wheel installs into a fresh environment and demo, track and bench run from $PWD"
