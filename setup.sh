#!/usr/bin/env bash
# Set up o3d-spectral on a fresh Debian/Ubuntu machine with python3.
#   ./setup.sh          library + harness (pandas, matplotlib, tqdm)
#   ./setup.sh dev      the same + test and lint tools
set -euo pipefail
cd "$(dirname "$0")"
if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
    # Open3D's wheel links against libusb-1.0.
    SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq libusb-1.0-0
fi
extra="harness"; [ "${1:-}" = "dev" ] && extra="dev"
python3 -m pip install -q -e ".[${extra}]"
