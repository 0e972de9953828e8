#!/bin/bash
# The zipper's output fingerprints (ownership scores, triangles, colours, positions) on samba-4cam
# frames 0, 5, ..., 35 and 39, with the bilateral filter and without: a change meant to leave the
# meshes alone must leave this list alone. Usage: scripts/zipper_fingerprints.sh [BUILD_DIR] | md5sum
set -euo pipefail
build=${1:-build}
for frame in 0 5 10 15 20 25 30 35 39; do
  for filter in "" --unfiltered; do
    echo "frame $frame ${filter:---filtered}"
    "$build/zf_zipper_repeat" --frame "$frame" $filter --repeat 1 | grep fingerprint
  done
done
