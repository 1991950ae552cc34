#!/usr/bin/env bash
# Installs every Debian 12 package the project needs. Idempotent: does nothing when all are present.
set -euo pipefail
packages=(
  cmake ninja-build ccache g++ clang libclang-rt-14-dev pkg-config
  libopenimageio-dev openimageio-tools libopenexr-dev libopencv-core-dev
  libgeographiclib-dev libproj-dev libgeotiff-dev libgdal-dev gdal-bin libtiff-dev libzstd-dev libdeflate-dev zlib1g-dev libzip-dev libexpat1-dev
  libsquish-dev libstb-dev libcli11-dev nlohmann-json3-dev libfmt-dev libcharls-dev libjxl-tools
  libgtest-dev libgmock-dev libbenchmark-dev
  libvulkan-dev mesa-vulkan-drivers vulkan-tools glslang-tools glslc spirv-tools vulkan-validationlayers
  libglfw3-dev xvfb xauth
  gdal-bin python3-gdal python3-numpy python-matplotlib-data
  slurm-wlm munge  # tests/cluster: a single-node Slurm cluster (daemons started by the test, not by init)
  libcurl4-openssl-dev  # format/remote: archives read from http(s):// URLs with range requests
  nginx-light openssl   # tests/format: the web server (and its certificate) the HTTP tests start themselves
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#packages[@]} Debian packages present"
  exit 0
fi
echo "setup: installing ${#missing[@]} Debian packages: ${missing[*]}"
sudo_cmd=()
[ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
"${sudo_cmd[@]}" apt-get update -o DPkg::Lock::Timeout=300 >/dev/null
DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y --no-install-recommends \
  -o DPkg::Lock::Timeout=300 "${missing[@]}"
