#!/usr/bin/env bash
# Idempotent set-up: Debian packages for Qt (xcb/offscreen), VTK and Xvfb, then .venv
# with `pip install -e .[test]`. Safe to run on every start; quiet when nothing to do.
set -euo pipefail

REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$REPO_ROOT/.venv"
STAMP="$VENV/.fluorogui-setup-stamp"

say() { echo "setup: $*" >&2; }
die() { echo "setup: ERROR: $*" >&2; exit 1; }

# Runtime libraries found with ldd/dlopen checks of PySide6 6.12 (xcb + offscreen
# platforms, xcb GL integrations) and VTK 9 (dlopens libGL/libEGL, libX11, libXcursor),
# plus Xvfb for tests and a font so Qt can draw text; libGLU, libXft and libXinerama for
# gmsh (STEP and IGES models, the cad extra, which the test extra includes).
DEBIAN_PACKAGES=(
  xvfb xauth
  libgl1 libegl1 libglx-mesa0 libegl-mesa0 libgl1-mesa-dri
  libx11-6 libx11-xcb1 libxcursor1 libxkbcommon0 libxkbcommon-x11-0
  libxcb1 libxcb-cursor0 libxcb-glx0 libxcb-icccm4 libxcb-image0 libxcb-keysyms1
  libxcb-randr0 libxcb-render0 libxcb-render-util0 libxcb-shape0 libxcb-shm0
  libxcb-sync1 libxcb-util1 libxcb-xfixes0 libxcb-xkb1
  libwayland-client0 libwayland-cursor0 libwayland-egl1
  libdbus-1-3 libfontconfig1 libfreetype6 fonts-dejavu-core libglib2.0-0
  libglu1-mesa libxft2 libxinerama1
)

PYTHON="${PYTHON:-python3}"

install_debian_packages() {
  if ! command -v dpkg-query >/dev/null 2>&1; then
    say "no dpkg: not a Debian-like system; install the equivalents of: ${DEBIAN_PACKAGES[*]}"
    return 0
  fi
  local wanted=("${DEBIAN_PACKAGES[@]}")
  # Debian's python3 needs python3-venv to create a virtual environment with pip.
  if [ ! -x "$VENV/bin/python" ] && ! "$PYTHON" -c "import ensurepip, venv" >/dev/null 2>&1; then
    wanted+=(python3-venv)
  fi
  local missing=() pkg
  for pkg in "${wanted[@]}"; do
    if [ "$(dpkg-query -W -f='${db:Status-Abbrev}' "$pkg" 2>/dev/null | cut -c1-2)" != "ii" ]; then
      missing+=("$pkg")
    fi
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ "$(id -u)" -ne 0 ]; then
    say "missing Debian packages; install them with:"
    say "  sudo apt-get update && sudo apt-get install -y --no-install-recommends ${missing[*]}"
    return 0
  fi
  say "installing Debian packages: ${missing[*]}"
  local log; log="$(mktemp)"
  if ! { DEBIAN_FRONTEND=noninteractive apt-get update -qq &&
         DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}"; } >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    rm -f "$log"
    die "apt-get install failed (see above)"
  fi
  rm -f "$log"
}

create_venv() {
  [ -x "$VENV/bin/python" ] && return 0
  command -v "$PYTHON" >/dev/null 2>&1 || die "$PYTHON not found; install Python >= 3.10"
  "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 10))' \
    || die "$("$PYTHON" --version 2>&1) is too old; fluorogui needs Python >= 3.10"
  say "creating $VENV with $("$PYTHON" --version 2>&1)"
  "$PYTHON" -m venv "$VENV" || die "could not create $VENV (on Debian: apt-get install python3-venv)"
}

pip_install() {
  local want
  want="$(cat "$REPO_ROOT/pyproject.toml" "$VENV/pyvenv.cfg" | sha256sum | cut -d' ' -f1)"
  if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$want" ] && [ -x "$VENV/bin/fluorogui" ]; then
    return 0
  fi
  say "installing fluorogui and its dependencies into .venv (pip install -e .[test])"
  local log; log="$(mktemp)"
  if ! "$VENV/bin/python" -m pip install -q --disable-pip-version-check -e "$REPO_ROOT[test]" >"$log" 2>&1; then
    tail -n 30 "$log" >&2
    rm -f "$log"
    die "pip install -e .[test] failed (see above)"
  fi
  rm -f "$log"
  echo "$want" >"$STAMP"
}

install_debian_packages
create_venv
pip_install
