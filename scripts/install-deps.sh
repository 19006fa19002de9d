#!/usr/bin/env bash
# Installs the Debian 12 packages areomap needs to build, test and run (the Python module
# included: python3-dev, python3-numpy, pybind11-dev, and python3-pytest for its tests; GNU
# parallel for the parallel executor, docs/cluster.md).
# Installs only what is missing; runs `apt-get update` at most once.
# Must run as root (or with sudo available). Safe to run repeatedly.
#   bash scripts/install-deps.sh              build, test and run
#   bash scripts/install-deps.sh --training   also what retraining the crater model needs
#                                             (scripts/crater_model/: PyTorch on the CPU; SciPy for
#                                             annotator_agreement.py's clustering)
#   bash scripts/install-deps.sh --fuzz       also what the libFuzzer targets need (clang and its
#                                             libFuzzer / sanitizer runtimes; scripts/fuzz.sh)
#   bash scripts/install-deps.sh --cluster    also Slurm and munge, to run plans on a Slurm
#                                             cluster of one (scripts/slurm-single-node.sh)
# The options combine.
set -euo pipefail

packages=(
  build-essential cmake ninja-build ccache pkg-config clang-format
  libeigen3-dev
  libopencv-dev libopencv-contrib-dev
  libceres-dev
  libcgal-dev
  libgeographiclib-dev geographiclib-tools
  libopenimageio-dev openimageio-tools
  libgdal-dev gdal-bin proj-bin
  libtbb-dev
  libfftw3-dev
  libcli11-dev
  nlohmann-json3-dev
  libgtest-dev libgmock-dev
  libbenchmark-dev
  python3-dev python3-numpy pybind11-dev python3-pytest
  parallel
)
for option in "$@"; do
  case "$option" in
    --training) packages+=(python3-torch python3-opencv python3-scipy) ;;
    # libFuzzer's runtime is only a Recommends of clang, which --no-install-recommends skips.
    --fuzz) packages+=(clang libclang-rt-14-dev) ;;
    --cluster) packages+=(slurm-wlm munge) ;;
    *)
      echo "error: install-deps: unknown option '$option' (expected --training, --fuzz, --cluster or nothing)" >&2
      exit 2
      ;;
  esac
done

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "error: install-deps needs root or sudo to install: ${missing[*]}" >&2; exit 1; }
  SUDO=sudo
fi

echo "install-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
