#!/usr/bin/env bash
# Install uvbake and everything it needs on a fresh Debian machine (run as root, or with sudo).
#   system: Open3D's runtime (libusb-1.0-0, libgl1, libegl1, libgomp1), headless rendering (libvulkan1,
#           mesa-vulkan-drivers), SuiteSparse for CHOLMOD and an optimised BLAS for it (reference BLAS
#           makes CHOLMOD's supernodal factorisation 2-4x slower), a compiler for scikit-sparse.
#           Chromium, headless, for the test that opens `uvbake batch`'s HTML report in a real browser.
#   python: uvbake with its cholmod, test and batch (Dask, pyarrow) extras, editable from this checkout.
set -euo pipefail
cd "$(dirname "$0")"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends \
    libusb-1.0-0 libgl1 libegl1 libgomp1 libvulkan1 mesa-vulkan-drivers \
    libsuitesparse-dev libopenblas0-pthread build-essential chromium >/dev/null
python3 -m pip install -q -c constraints.txt -e ".[cholmod,test,batch]"
# the Khronos glTF validator, used by the tests to check exported GLB files
if ! command -v npm >/dev/null; then $SUDO apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null; fi
npm install --silent --no-audit --no-fund --prefix "${UVBAKE_NODE_PREFIX:-$HOME/.cache/uvbake/node}" \
    gltf-validator@2.0.0-dev.3.10 >/dev/null
python3 -c "import uvbake, open3d, nlopt, sksparse.cholmod, distributed, pyarrow; print('uvbake', uvbake.__version__, 'installed; open3d', open3d.__version__)"
