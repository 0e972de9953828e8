#!/usr/bin/env bash
# Runs every benchmark and writes docs/benchmarks.md from the results (make bench).
# Raw results (JSON) go to $BENCH_OUT (default out/bench). Needs ../shared/data/samba-4cam.
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR=${BUILD_DIR:-build}
OUT=${BENCH_OUT:-out/bench}
SAMBA=${SAMBA:-../shared/data/samba-4cam}
FRAMES=${BENCH_FRAMES:-40}
SOAK=${BENCH_SOAK:-1000}
SCALE_FRAMES=${BENCH_SCALE_FRAMES:-10}
PAIRED_ROUNDS=${BENCH_PAIRED_ROUNDS:-5}
SCALE_ROUNDS=${BENCH_SCALE_ROUNDS:-5}
ZF=$BUILD_DIR/zipfusion
mkdir -p "$OUT"
[[ -f "$SAMBA/rig.json" ]] || { echo "bench.sh: $SAMBA/rig.json: not found (the samba-4cam capture of ../shared/data)" >&2; exit 2; }

# A synthetic capture, written beside its final place and moved there once complete, so an
# interrupted run never leaves a half-written capture to be reused.
synth_once() {
  local capture=$1
  shift
  [[ -f "$capture/rig.json" ]] && return
  rm -rf "$capture" "$capture.partial"
  "$ZF" synth --out "$capture.partial" "$@" > /dev/null
  mv "$capture.partial" "$capture"
}

step() { echo "== $*" >&2; }

step "samba-4cam: stages, threads, coarse-to-fine, memory over $SOAK frame sets"
"$ZF" bench "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --frames "$FRAMES" --repeat 3 --soak "$SOAK" --json > "$OUT/samba.json"

# Where zippering's time goes, as instructions by function: callgrind counts them the same in any
# phase of the machine's speed, so they show what the wall times above cannot separate. samba-4cam
# frame 0 on one thread, unfiltered (issue 4's case) and with the paper's filter, zippered 3 and 6
# times: the difference is three calls in steady state (the first call also grows the buffers).
rm -f "$OUT"/callgrind_*  # the report reads what it finds
if command -v valgrind > /dev/null; then
  step "samba-4cam: callgrind's instructions of zippering by function"
  zipper_function=$("$BUILD_DIR/zf_zipper_repeat" --callgrind-function)
  for depth in unfiltered filtered; do
    flags=(--capture "$SAMBA")
    [[ "$depth" == unfiltered ]] && flags+=(--unfiltered)
    for calls in 3 6; do
      name="callgrind_${depth}_$calls"
      valgrind --tool=callgrind --callgrind-out-file="$OUT/$name.out" "--toggle-collect=$zipper_function" \
        "$BUILD_DIR/zf_zipper_repeat" "${flags[@]}" --repeat "$calls" --threads 1 > /dev/null 2> "$OUT/$name.log"
      # Every function, not only those making up 99 % (callgrind_annotate's default): a part near 1 %
      # would drop out of one listing and be counted wrong.
      callgrind_annotate --inclusive=yes --threshold=100 "$OUT/$name.out" > "$OUT/$name.txt"
    done
  done
else
  step "valgrind missing (scripts/install-deps.sh installs it): no instructions by function"
fi
step "samba-4cam: quality of each mode (reconstruct + eval)"
for mode in zipper separate; do
  # bilateral5x5: the filter over 5×5 pixels (σ 2 px), as `zipfusion bench`'s "+5x5 filter" columns.
  for filter in bilateral bilateral5x5 none; do
    name="${mode}_${filter}"
    flags=(--filter "$filter")
    [[ "$filter" == bilateral5x5 ]] && flags=(--filter bilateral --bilateral-radius 2 --bilateral-sigma-px 2)
    rm -rf "$OUT/meshes/$name"  # a run of other frames left there would be refused (reconstruct keeps eval from mixing runs)
    "$ZF" reconstruct "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --register off --frames "0:$FRAMES" --mode "$mode" "${flags[@]}" \
      --out "$OUT/meshes/$name" > /dev/null
    "$ZF" eval "$SAMBA" "$OUT/meshes/$name" --frames "0:$FRAMES" --json > "$OUT/eval_$name.json"
  done
done
for filter in bilateral none; do
  name="zipper_${filter}_lod1"
  rm -rf "$OUT/meshes/$name"
  "$ZF" reconstruct "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --register off --frames "0:$FRAMES" --filter "$filter" --lod 1 \
    --out "$OUT/meshes/$name" > /dev/null
  "$ZF" eval "$SAMBA" "$OUT/meshes/$name" --frames "0:$FRAMES" --json > "$OUT/eval_$name.json"
done
# Pieces of fewer than 50 triangles dropped (`--min-component 50`), as bench's "zipper min component 50".
name=zipper_none_min50
rm -rf "$OUT/meshes/$name"
"$ZF" reconstruct "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --register off --frames "0:$FRAMES" --filter none --min-component 50 \
  --out "$OUT/meshes/$name" > /dev/null
"$ZF" eval "$SAMBA" "$OUT/meshes/$name" --frames "0:$FRAMES" --json > "$OUT/eval_$name.json"

if [[ -x "$BUILD_DIR/zf_open3d_compare" ]]; then
  step "Open3D TSDF (two volumes; 10 mm, 5 mm) and Poisson, same frames"
  # The legacy volume's results are open3d_VOXEL, with Poisson at 10 mm; the tensor one's (the
  # faster of the two here) open3d_block_VOXEL.
  for tsdf in scalable voxel-block-grid; do
    prefix=open3d_
    [[ "$tsdf" == voxel-block-grid ]] && prefix=open3d_block_
    for voxel in 0.01 0.005; do
      poisson=--no-poisson
      [[ "$tsdf" == scalable && "$voxel" == 0.01 ]] && poisson="--poisson-frame 0"
      # shellcheck disable=SC2086
      "$BUILD_DIR/zf_open3d_compare" "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --frames "0:$FRAMES" --voxel "$voxel" $poisson \
        --tsdf "$tsdf" --out "$OUT/meshes/$prefix$voxel" --json > "$OUT/$prefix$voxel.json"
      "$ZF" eval "$SAMBA" "$OUT/meshes/$prefix$voxel" --frames "0:$FRAMES" --json > "$OUT/eval_$prefix$voxel.json"
    done
  done
  "$ZF" eval "$SAMBA" "$OUT/meshes/open3d_0.01/poisson" --frames 0 --json > "$OUT/eval_poisson.json"
  # The machine's speed changes by up to a third from minute to minute, so the ratio is also
  # measured in rounds that alternate the two, each round's ratio taken within it.
  step "zipfusion and Open3D's tensor TSDF at 10 mm in $PAIRED_ROUNDS alternating rounds"
  rm -f "$OUT"/paired_zipfusion_*.json "$OUT"/paired_open3d_*.json  # the report reads every round it finds
  for round in $(seq 1 "$PAIRED_ROUNDS"); do
    "$ZF" bench "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --frames "$FRAMES" --repeat 1 --json > "$OUT/paired_zipfusion_$round.json"
    "$BUILD_DIR/zf_open3d_compare" "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --frames "0:$FRAMES" --voxel 0.01 --no-poisson \
      --tsdf voxel-block-grid --out "$OUT/meshes/paired_open3d" --json > "$OUT/paired_open3d_$round.json"
  done
fi

# The rigs are benched in rounds, each round every rig once, so that all of them meet the same
# phases of the machine's speed and their ratios can be taken within a round.
step "scaling: synthetic rigs of 2, 4, 6, 8 cameras and three depth sizes, $SCALE_ROUNDS rounds"
rigs=()
for cameras in 2 4 6 8; do
  synth_once "$OUT/synth/cameras_$cameras" --cameras "$cameras" --frames "$SCALE_FRAMES"
  rigs+=("cameras_$cameras")
done
for size in 320x240 640x480 1280x960; do
  synth_once "$OUT/synth/size_$size" --cameras 4 --frames "$SCALE_FRAMES" --resolution "$size"
  rigs+=("size_$size")
done
rm -f "$OUT"/scale_*.json  # the report reads every round it finds
for round in $(seq 1 "$SCALE_ROUNDS"); do
  # Every other round in reverse, so that no rig always runs first or last in a round.
  order=("${rigs[@]}")
  if (( round % 2 == 0 )); then
    order=()
    for (( k = ${#rigs[@]} - 1; k >= 0; k-- )); do order+=("${rigs[k]}"); done
  fi
  for rig in "${order[@]}"; do
    "$ZF" bench "$OUT/synth/$rig" --frames "$SCALE_FRAMES" --repeat 1 --json > "$OUT/scale_${rig}_$round.json"
  done
done

step "live stream: Draco frame size, 20 viewers (one stalled), latency to a client and to a browser"
serve_log="$OUT/serve.log"
"$ZF" serve "$SAMBA" --rig "$SAMBA/ground_truth/rig.json" --register off --loop --port 0 --seconds 90 > "$serve_log" 2>&1 &
serve_pid=$!
for _ in $(seq 100); do grep -q "serving http" "$serve_log" && break; sleep 0.2; done
url=$(grep -o "serving http://[^ ]*" "$serve_log" | head -1 | cut -d" " -f2)
port=$(echo "$url" | sed -E 's|.*:([0-9]+)/.*|\1|')
sleep 3  # the loop's first pass decodes the frames
"$BUILD_DIR/zf_stream_clients" --port "$port" --clients 20 --stalled 1 --seconds 15 --json > "$OUT/stream_clients.json"
"$BUILD_DIR/zf_stream_clients" --port "$port" --clients 1 --stalled 0 --seconds 10 --json > "$OUT/stream_one_client.json"
# The viewer's wide flow window: frames are made only when a viewer has room, so one that keeps up needs it.
"$BUILD_DIR/zf_stream_clients" --port "$port" --clients 1 --stalled 0 --window 3 --seconds 10 --json > "$OUT/stream_flow_client.json"
node bench/stream_latency.mjs "$url" --seconds 20 > "$OUT/stream_browser.json"
kill -TERM "$serve_pid" 2> /dev/null || true
wait "$serve_pid" 2> /dev/null || true
"$BUILD_DIR/zf_draco_bench" "$SAMBA" --frames "$FRAMES" --json > "$OUT/stream_draco.json"

step "kernels (Google Benchmark)"
"$BUILD_DIR/zf_kernel_bench" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true --benchmark_format=json > "$OUT/kernels.json"
"$BUILD_DIR/zf_micro_bench" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true --benchmark_format=json > "$OUT/micro.json"

step "writing docs/benchmarks.md and the README's summary of it"
python3 scripts/bench_report.py "$OUT" > docs/benchmarks.md.tmp
mv docs/benchmarks.md.tmp docs/benchmarks.md
python3 scripts/bench_report.py "$OUT" --readme README.md
echo "wrote docs/benchmarks.md and the README's summary (raw results in $OUT)"
