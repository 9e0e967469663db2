#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# Installs the Debian 12 packages FTM needs to build and test. Idempotent:
# does nothing when everything is already installed. Run as root or with sudo.
#
#   deploy/install-deps.sh          build + test dependencies
#
set -euo pipefail
case ${1:-} in
  '') ;;
  -h|--help) sed -n 's/^#   \(deploy\/install-deps.sh\) .*/usage: \1 (no arguments)/p' "$0"; exit 0 ;;
  *) echo "install-deps: takes no arguments (got '$1')" >&2; exit 2 ;;
esac

packages=(
  build-essential cmake ninja-build pkg-config   # toolchain
  clang                                           # second compiler: determinism check
  libclang-rt-14-dev                              # libFuzzer + sanitizers for clang (tests/fuzz)
  libcmocka-dev                                   # unit tests
  zlib1g-dev                                      # libftm: .nii.gz volumes through libnifti's znzlib
  libnifti2-dev                                   # libftm: NIfTI-1/-2 volumes and label maps (optional)
  libassimp-dev                                   # ftm_stl: STL surfaces (-DFTM_BUILD_STL=OFF without)
  libcgal-dev                                     # ftm-mesh: tissue meshes from scans (optional; GPL-3+)
  gnuplot-nox                                     # benchmark plots in docs/
  libsuitesparse-dev                              # FEM reference (CHOLMOD)
  calculix-ccx                                    # CalculiX: re-runs the FEM references (tests/calculix)
  libbullet-dev                                   # ftm bench peers: Bullet's soft body (optional)
  cyclonedds-dev cyclonedds-tools                 # DDS transport, idlc, ddsperf
  libddsc0debian                                  # DDS Security plugins (--security)
  openssl libssl-dev                              # deploy/ftm-security; bundle checks in ftm_wire
  libprotobuf-c-dev protobuf-c-compiler           # wire protocol codec
  libuv1-dev                                      # ftm-server event loop
  libmicrohttpd-dev                               # ftm-server Prometheus metrics endpoint
  libglfw3-dev libgl-dev libgl1-mesa-dri libpng-dev  # ftm-client: window, OpenGL 3.3, screenshots
  xvfb xauth                                      # headless X server for client tests
  xdotool                                         # test_client_gl_reset: a trainee's mouse and keys
  python3                                         # test scripts' checks, ftm-plot-forces' names
  iproute2                                        # test_two_hosts: network namespaces, veth
  tcpdump                                         # test_net_secure_capture: what a listener records
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "install-deps: run as root (missing: ${missing[*]})" >&2; exit 1; }
  SUDO=sudo
fi
echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
