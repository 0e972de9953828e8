#!/usr/bin/env bash
# Installs every Debian package that zipfusion's build, tests and benchmarks need.
# Idempotent: packages already present are skipped, and apt is only asked when something is missing.
# --fuzz adds what `make fuzz` needs besides (clang and its libFuzzer runtime).
set -euo pipefail

packages=(
  build-essential cmake pkg-config
  libeigen3-dev                      # small fixed-size maths
  libopencv-dev                      # image encoding and ops, calibration
  libpng-dev libjpeg-dev             # PNG and JPEG decoding (every problem an error, nothing printed)
  nlohmann-json3-dev                 # rig.json, stats.json
  libcli11-dev                       # command line
  libcgal-dev                        # 2-D Delaunay triangulation of seams
  libnanoflann-dev                   # k-d trees: closest points for registration
  libceres-dev                       # bundle adjustment (calibration)
  libdraco-dev                       # mesh compression for the live stream
  libboost-dev                       # Boost.Beast: HTTP and WebSocket server of the live stream
  libfreenect-dev                    # live Kinect v1 capture (record, reconstruct --live); pulls libfreenect0.5, which ships fakenect's libfreenect.so
  libfreenect-bin                    # the fakenect wrapper script: the live tests replay recordings through it
  libgtest-dev libgmock-dev          # tests
  bsdutils                           # script(1): a test runs a command on a terminal (Debian installs it everywhere)
  libbenchmark-dev                   # micro-benchmarks
  valgrind                           # bench: callgrind's instruction counts of zippering by function (docs/benchmarks.md)
  python3                            # scripts/bench_report.py writes docs/benchmarks.md
  chromium                           # the viewer's tests run in a real (headless) browser
  libopen3d-dev                      # bench only: Open3D TSDF/Poisson side by side (never in the library)
)
if [ "${1:-}" = "--fuzz" ]; then
  packages+=(clang libclang-rt-dev)  # libFuzzer, ASan and UBSan runtimes for the fuzz targets
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

# Node.js and npm build the viewer (web/: three.js from the npm registry, bundled at build time).
# Many machines bring their own Node.js; Debian's is installed only when there is none.
if ! command -v node >/dev/null 2>&1; then missing+=(nodejs); fi
if ! command -v npm >/dev/null 2>&1; then missing+=(npm); fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
