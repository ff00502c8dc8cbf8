#!/usr/bin/env bash
# Installs every Debian 12 package slamvdb needs and builds it in Release.
# Usage: scripts/setup.sh            (install + build)
#        SLAMVDB_SKIP_APT=1 scripts/setup.sh   (build only)
#        SLAMVDB_UNITY=OFF scripts/setup.sh    (one translation unit per source: quicker rebuilds
#                                               after small edits, slower full builds)
#        SLAMVDB_WERROR=ON scripts/setup.sh    (warnings are errors: what CI builds with)
# A unity build (CMake merges up to 16 sources of a target into one translation unit, so Eigen,
# OpenCV, Torch, gtest and fmt are parsed once per batch, not once per file) is the default: it
# halves a full build, which is what a fresh machine and CI do.
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  lld                    # links the Release tree's executables (below)
  libeigen3-dev          # linear algebra, poses
  libtbb-dev             # parallel loops
  libopencv-dev          # images, PNG/JPEG, projectPoints
  libsqlite3-dev         # map store
  libspdlog-dev libfmt-dev  # logging
  libabsl-dev            # flat hash maps (voxel blocks, semantic index)
  libcli11-dev           # CLI
  nlohmann-json3-dev     # manifests, metadata, the server's JSON
  libcpp-httplib-dev libssl-dev  # `slamvdb serve`: HTTP server (Debian builds it with OpenSSL: optional TLS)
  libfaiss-dev  # `slamvdb serve`: the ANN index of top-k queries (query/ann_index.cpp; k-means + centroid search)
  openssl                # the serve TLS test makes a self-signed certificate
  libyaml-cpp-dev        # transforms.yaml, ontology
  zlib1g-dev             # CLIP merge list (.gz)
  libicu-dev             # Unicode categories, case folding, NFC for the CLIP tokenizer
  python3-regex          # test oracle for the CLIP tokenizer
  python3-yaml           # the serve test reads docs/openapi.yaml
  libgtest-dev libgmock-dev  # tests
  libbenchmark-dev       # benchmarks
  liboctomap-dev         # side-by-side occupancy benchmark baseline
  libtorch-dev libopenblas0-pthread  # TorchScript inference (+ fast BLAS)
  python3-torch python3-numpy        # tests trace small TorchScript models
  pybind11-dev python3-dev python3-pytest  # the Python module and its tests
  python3-mypy                       # its type stubs checked against it (stubtest)
  libceres-dev libnanoflann-dev liblzf-dev  # localization: pose graph, ScanContext k-d tree, PCD binary_compressed
  libpqxx-dev libpq-dev postgresql-15 postgresql-15-postgis-3  # the fleet map (PostgreSQL + PostGIS); tests start their own servers
  clang libclang-rt-14-dev           # sanitizer build (ASan + UBSan) and libFuzzer harnesses (scripts/fuzz.sh)
  libomp-dev             # OpenMP for the clang builds: faiss (query/ann_index.cpp) needs it
  chromium                           # the HTML viewer's test (headless, driven by playwright-core)
  liblz4-dev libzstd-dev libbz2-dev  # recordings: lz4, zstd and bz2 compressed chunks (MCAP, ROS 1 bags, rosbag2)
  python3-rosbag python3-sensor-msgs python3-geometry-msgs python3-nav-msgs python3-tf2-msgs
                                     # tests: ROS 1 bags written by ROS's own writer (not by our reader's code)
  zstd lz4                           # reference decompressors for the recording benchmarks
)
# Node.js and npm (three.js, esbuild and playwright-core for the HTML viewer, from the npm
# registry): Debian's, unless the machine already has them.
command -v npm > /dev/null || PACKAGES+=(nodejs npm)

if [ "${SLAMVDB_SKIP_APT:-0}" != "1" ]; then
  missing=()
  for p in "${PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    SUDO=""; [ "$(id -u)" != 0 ] && SUDO=sudo
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
  fi
fi

# npm packages, exactly as locked: the viewer's (three.js, esbuild, playwright-core) and the
# recording tests' independent writers (MCAP, CDR, ROS 1 serialization).
for dir in viewer tests/recording_fixtures; do
  if [ ! -f $dir/node_modules/.package-lock.json ] || ! cmp -s $dir/package-lock.json $dir/node_modules/.slamvdb-lock; then
    npm ci --prefix $dir --no-audit --no-fund --loglevel=error
    cp $dir/package-lock.json $dir/node_modules/.slamvdb-lock
  fi
done

# Executables are linked by lld, not GNU ld: the test binary, the CLI and the benchmarks link in 0.5-1.6
# instead of 4.5-5 CPU-s each (on the build's critical path: the test binary's link is its last step).
# Shared and module libraries stay with GNU ld: the Python module is linked with GCC's LTO
# (pybind11), which lld cannot read.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD="${SLAMVDB_UNITY:-ON}" \
  -DCMAKE_UNITY_BUILD_BATCH_SIZE=16 -DSLAMVDB_WERROR="${SLAMVDB_WERROR:-OFF}" -DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=lld
cmake --build build -j"$(nproc)"
