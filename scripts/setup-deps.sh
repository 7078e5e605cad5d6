#!/bin/sh
# Install the Debian 12 packages sepbrdf needs, only those that are missing.
# Idempotent and quiet when everything is present. Run as root (or via sudo).
#   scripts/setup-deps.sh          build + test dependencies
#   scripts/setup-deps.sh --bench  only the optional peers of bench/run.sh
#                                  (numpy, scipy, scikit-learn; not for the tests)
set -eu

PKGS="cmake make gcc pkg-config liblapacke-dev libopenblas-dev libopenexr-dev \
openexr glslang-tools libpng-dev gnuplot-nox libosmesa6-dev libegl-dev \
libgles-dev libgl-dev libgl1-mesa-dri clang libclang-rt-14-dev clang-format chromium \
libopenmpi-dev openmpi-bin python3 python3-numpy python3-pytest spirv-cross"
if [ "${1:-}" = --bench ]; then PKGS="python3 python3-numpy python3-scipy python3-sklearn"; fi

missing=""
for p in $PKGS; do
    if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
        missing="$missing $p"
    fi
done
[ -z "$missing" ] && exit 0

SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
echo "setup-deps: installing$missing" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq >/dev/null
# shellcheck disable=SC2086
$SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
