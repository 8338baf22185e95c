#!/usr/bin/env bash
# Installs what probecal needs on Debian 12: OpenCV 4.6 with contrib, clang for
# the opencv crate's bindings, libjpeg-turbo's TurboJPEG (the JPEG codec OpenCV
# itself uses, called directly), the fonts figures use, and the readers the report
# tests check the reports in (pdflatex with the LaTeX report's packages, Chromium),
# ADMesh, the independent STL reader the printable phantom is checked with, and
# python3-opencv, OpenCV's own calibration sample the camera calibration is
# checked against, numpy (the plain reference scripts/wire-lines.py measures with),
# and two OpenIGTLink implementations the live stream is tested
# with: libopenigtlink-dev (the protocol's reference library, Debian) and pyigtl
# (PyPI, in a virtual environment).
# Safe to run again.
set -euo pipefail

packages=(libopencv-dev libopencv-contrib-dev clang libclang-dev fonts-dejavu-core pkg-config admesh
  texlive-latex-recommended texlive-latex-extra texlive-science lmodern chromium python3-opencv python3-numpy python3-venv
  libopenigtlink-dev g++ libturbojpeg0-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "installing: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
command -v cargo >/dev/null || { echo "cargo is not installed: install Rust (rustup) first" >&2; exit 1; }
# The test command checks formatting and lints.
for tool in clippy rustfmt; do
  cargo "${tool/rustfmt/fmt}" --version >/dev/null 2>&1 || rustup component add "$tool"
done
# The OpenIGTLink replay server of tests/live_igtl.rs (PROBECAL_PYIGTL_VENV).
venv="${PROBECAL_PYIGTL_VENV:-/var/tmp/probecal-pyigtl}"
if ! "$venv/bin/python3" -c 'import pyigtl' >/dev/null 2>&1; then
  echo "installing pyigtl into $venv"
  /usr/bin/python3 -m venv "$venv"
  "$venv/bin/python3" -m pip install --quiet --disable-pip-version-check pyigtl==0.3.4
fi
