#!/usr/bin/env bash
# Installs the Debian 12 packages the toolkit needs (as root), then configures and builds
# it in Release into ./build. Used by both README commands and by CI (.ci/run).
set -euo pipefail
cd "$(dirname "$0")/.."

source tools/apt_install.sh
install_missing setup \
  cmake g++ make pkg-config \
  libeigen3-dev libhdf5-dev libopenimageio-dev openimageio-tools libflann-dev liblz4-dev \
  libglm-dev catch2 libtomlplusplus-dev libcli11-dev fonts-dejavu-core hdf5-tools libgdal-dev \
  libopenmpi-dev openmpi-bin libnlopt-dev python3-numpy python3-h5py \
  chromium groff-base r-base-core r-cran-hdf5r r-cran-spatstat.geom
# chromium: the tests of the HTML reports load them in headless Chromium (ctest -L browser;
# docs/report.md). groff-base: the man page test renders eco.1 with groff -ww (docs/install.md).
# R with hdf5r and spatstat.geom: the test of the R recipe (R/ecotoolkit.R: outputs to a
# spatstat ppp; ctest -L r; docs/r.md), about 30 s to install. None is needed to build or
# run eco.

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release
cmake --build build -j"$(nproc)"
