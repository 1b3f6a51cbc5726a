#!/usr/bin/env bash
# Installs the Debian 12 packages pbdbench needs, and nothing when all are present.
# Idempotent: a second run costs one dpkg-query. Uses sudo only when not already root.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config
  libeigen3-dev libsundials-dev libceres-dev libsuitesparse-dev libhdf5-dev zlib1g-dev
  libdeflate-dev               # runfile/frame_compressor.cpp: the frames' zlib streams
  libtomlplusplus-dev libcli11-dev libfmt-dev libgtest-dev libbenchmark-dev nlohmann-json3-dev
  python3-matplotlib python3-h5py python3-numpy
  clang-14 libclang-rt-14-dev  # scripts/fuzz.sh: libFuzzer and the sanitizers
  libomp-14-dev                # scripts/fuzz.sh: OpenMP for clang (solvers/: g++ has its libgomp)
  python3-paraview  # pvbatch: the tests read the ParaView output with ParaView's own XDMF reader
                    # (Debian's python3-vtk9 has no XDMF reader)
  xvfb xauth        # xvfb-run: ParaView renders (scripts/paraview_screenshot.py) without a display
  python3-meshio    # tests/runfile/test_xdmf.py: the ParaView output read by meshio too (XDMF 3)
  ffmpeg            # scripts/animate.py: MP4 animations
)

missing=()
for p in "${PACKAGES[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

if [[ ${#missing[@]} -eq 0 ]]; then
  exit 0
fi

echo "pbdbench: installing missing Debian packages: ${missing[*]}" >&2
SUDO=()
if [[ $(id -u) -ne 0 ]]; then
  command -v sudo >/dev/null || { echo "pbdbench: need root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO=(sudo)
fi
export DEBIAN_FRONTEND=noninteractive
"${SUDO[@]}" apt-get update -qq
"${SUDO[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
