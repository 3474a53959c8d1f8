#!/usr/bin/env bash
# Sets up a fresh machine: system library for Open3D, a virtualenv in .venv, every SofIA package
# (editable) and the test tools. Safe to run again; it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

PY=${PYTHON:-python3}
VENV=${SOFIA_VENV:-.venv}

# Open3D links libusb-1.0 and libgomp at import time.
if ! ldconfig -p 2>/dev/null | grep -q "libusb-1.0.so.0" || ! ldconfig -p 2>/dev/null | grep -q "libgomp.so.1"; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && command -v sudo >/dev/null && SUDO=sudo
  echo "[install] apt-get install libusb-1.0-0 libgomp1"
  $SUDO apt-get update -qq >/dev/null
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq libusb-1.0-0 libgomp1 >/dev/null
fi

if [ ! -x "$VENV/bin/python" ]; then
  echo "[install] creating $VENV"
  "$PY" -m venv "$VENV"
fi

stamp="$VENV/.sofia-installed"
inputs=$(cat constraints.txt requirements-dev.txt schemas/pyproject.toml runtime/pyproject.toml \
  system/pyproject.toml replay/pyproject.toml services/*/pyproject.toml | sha256sum | cut -d' ' -f1)
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$inputs" ]; then
  exit 0
fi
echo "[install] pip install (SofIA packages + test tools)"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -c constraints.txt \
  -e "schemas[ros]" -e "runtime[ros]" -e "system[demo]" -e "replay[synth]" -e services/detector \
  -e services/calibrator -e services/gripper -e "services/camera[sim]" -e services/viz \
  -e "services/arm[sim,calibrate]" -r requirements-dev.txt
# the camera's and the calibrator's compiled kernels into numba's cache, so the
# first `sofia camera serve` starts at once and the first calibration does not compile (~15 s)
"$VENV/bin/python" -c "from sofia_camera.pipeline import warm_kernels; warm_kernels()"
"$VENV/bin/python" -c "from sofia_calibrator.fitting.warm import warm_kernels; warm_kernels()"
echo "$inputs" > "$stamp"
echo "[install] done: $("$VENV/bin/sofia" --version) installed in $VENV"
