#!/usr/bin/env bash
# Set up o3d-spectral on a fresh Debian/Ubuntu machine with python3, in a virtual environment
# (stock Debian 12 / Ubuntu 24.04 Pythons refuse system-wide pip installs, PEP 668).
#   ./setup.sh          library + harness (pandas, matplotlib, tqdm) into .venv/
#   ./setup.sh dev      the same + test and lint tools
#   O3D_SPECTRAL_VENV=/path/to/venv ./setup.sh    use (or create) that environment instead
set -euo pipefail
cd "$(dirname "$0")"
SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
missing=()
# Open3D's wheel links against libusb-1.0.
ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0' || missing+=(libusb-1.0-0)
# Debian/Ubuntu ship venv (ensurepip) separately from python3.
python3 -c 'import ensurepip, venv' 2>/dev/null || missing+=("python3-venv")
if [ "${#missing[@]}" -gt 0 ]; then
    $SUDO apt-get update -qq
    $SUDO apt-get install -y -qq "${missing[@]}"
fi
venv="${O3D_SPECTRAL_VENV:-.venv}"
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
extra="harness"; [ "${1:-}" = "dev" ] && extra="dev"
"$venv/bin/python" -m pip install -q --upgrade pip
"$venv/bin/python" -m pip install -q -e ".[${extra}]"
# Compile the numba kernels now (cached on disk), not on the first registration.
"$venv/bin/python" -m o3d_spectral.spectra.kernels
