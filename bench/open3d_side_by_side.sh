#!/usr/bin/env bash
# Open3D side by side (issue 6): Open3D TSDF at 10 and 5 mm (and Poisson on one frame) against
# zipfusion's zipper and separate modes, with and without the bilateral filter, on the same frames
# with the true poses; every output scored by `zipfusion eval`. Prints a Markdown table.
#
#   [ROUNDS=3] [THREADS=0] bench/open3d_side_by_side.sh [CAPTURE] [FRAMES] [OUT]
#     defaults: ../shared/data/samba-4cam 0:40 out/open3d_side_by_side; BUILD=build
#
# Needs build/zipfusion and build/zf_open3d_compare (libopen3d-dev), GNU time (peak RSS) and
# python3 (the table). Run from the repository root.
set -euo pipefail

capture=${1:-../shared/data/samba-4cam}
frames=${2:-0:40}
out=${3:-out/open3d_side_by_side}
build=${BUILD:-build}
threads=${THREADS:-0}  # both tools; 0 = all cores
rig="$capture/ground_truth/rig.json"
first=${frames%%:*}
first=${first:-0}

for tool in "$build/zipfusion" "$build/zf_open3d_compare" /usr/bin/time; do
  [ -x "$tool" ] || { echo "open3d_side_by_side: $tool: not found (build first; zf_open3d_compare needs libopen3d-dev)" >&2; exit 2; }
done
mkdir -p "$out"

# name, then the command; peak RSS (kB) by GNU time; the load average before each run.
run() {
  local dir=$1 name=$2
  shift 2
  echo "== $dir/$name: $*" >&2
  cut -d' ' -f1 /proc/loadavg > "$dir/$name.load"
  /usr/bin/time -f %M -o "$dir/$name.rss_kb" "$@" > "$dir/$name.log"
}

# Timings on a shared machine are noisy: every method runs once per round, the rounds interleave
# the methods, and the table pools the per-frame times of all rounds. Quality is scored on round 1.
rounds=${ROUNDS:-3}
for round in $(seq 1 "$rounds"); do
  dir="$out/round$round"
  mkdir -p "$dir"
  run "$dir" o3d_10mm "$build/zf_open3d_compare" "$capture" --rig "$rig" --frames "$frames" --voxel 0.01 --poisson-frame "$first" --threads "$threads" --out "$dir/o3d_10mm"
  run "$dir" o3d_5mm "$build/zf_open3d_compare" "$capture" --rig "$rig" --frames "$frames" --voxel 0.005 --no-poisson --threads "$threads" --out "$dir/o3d_5mm"
  for mode in zipper separate; do
    for filter in bilateral none; do
      run "$dir" "zf_${mode}_${filter}" "$build/zipfusion" reconstruct "$capture" --rig "$rig" --frames "$frames" --mode "$mode" --filter "$filter" --threads "$threads" \
        --out "$dir/zf_${mode}_${filter}"
    done
  done
done

# zipfusion's own benchmark: the same frame sets decoded once beforehand (no decoding thread
# competing for the cores), every configuration --repeat times. It takes the first N frame sets.
count=$(( ${frames##*:} - first ))
if [ "$first" -eq 0 ]; then
  echo "== zipfusion bench --frames $count --repeat $rounds" >&2
  "$build/zipfusion" bench "$capture" --rig "$rig" --frames "$count" --repeat "$rounds" --threads "$threads" --json > "$out/zf_bench.json"
fi

for name in o3d_10mm o3d_5mm zf_zipper_bilateral zf_zipper_none zf_separate_bilateral zf_separate_none; do
  echo "== eval $name" >&2
  "$build/zipfusion" eval "$capture" "$out/round1/$name" --frames "$frames" --json > "$out/$name.eval.json"
done
echo "== eval o3d_10mm/poisson" >&2
"$build/zipfusion" eval "$capture" "$out/round1/o3d_10mm/poisson" --frames "$first" --json > "$out/poisson.eval.json"

python3 - "$out" "$rounds" "$threads" <<'EOF'
import json, math, sys
out, rounds = sys.argv[1], int(sys.argv[2])
def load(path):
    with open(path) as f:
        return json.load(f)
def pct(values, p):
    v = sorted(values)
    if p == 50:
        n = len(v)
        return v[n // 2] if n % 2 else 0.5 * (v[n // 2 - 1] + v[n // 2])
    return v[max(math.ceil(p / 100 * len(v)), 1) - 1]
import os
bench = load(f"{out}/zf_bench.json") if os.path.exists(f"{out}/zf_bench.json") else None
def bench_ms(config):
    if not bench:
        return None
    for c in bench["configs"]:
        if c["name"] == config:
            return c["ms"]["total"]
    return None
rows = []
loads = []
for name, label, config in [("o3d_10mm", "Open3D TSDF 10 mm", None), ("o3d_5mm", "Open3D TSDF 5 mm", None),
                            ("zf_zipper_bilateral", "zipfusion zipper, bilateral", "zipper+filter"),
                            ("zf_zipper_none", "zipfusion zipper, --filter none", "zipper"),
                            ("zf_separate_bilateral", "zipfusion separate, bilateral", "separate+filter"),
                            ("zf_separate_none", "zipfusion separate, --filter none", "separate")]:
    totals, prep, rss = [], [], 0
    for r in range(1, rounds + 1):
        stats = load(f"{out}/round{r}/{name}/stats.json")
        if name.startswith("o3d"):
            totals += [f["ms"]["total"] for f in stats["tsdf"]["per_frame"]]
            prep += [f["ms"]["prepare"] for f in stats["tsdf"]["per_frame"]]
        else:
            totals += [f["ms"]["total"] for f in stats["frames"]]
        rss = max(rss, int(open(f"{out}/round{r}/{name}.rss_kb").read().split()[-1]) / 1024)
        loads.append(float(open(f"{out}/round{r}/{name}.load").read()))
    rows.append((label, pct(totals, 50), pct(totals, 95), pct(prep, 50) if prep else None, bench_ms(config) if config else None,
                 load(f"{out}/{name}.eval.json")["mean"], rss))
poisson = [load(f"{out}/round{r}/o3d_10mm/stats.json")["poisson"] for r in range(1, rounds + 1)]
rows.append((f"Open3D Poisson depth 8 (frame {poisson[0]['frame']} only)", pct([p["ms"]["total"] for p in poisson], 50), None,
             pct([p["ms"]["prepare"] for p in poisson], 50), None, load(f"{out}/poisson.eval.json")["mean"], None))
print(f"{rounds} rounds, threads {sys.argv[3]} (0 = all cores); load average (1 min) before the runs: {min(loads):.1f} to {max(loads):.1f}")
print("Poisson ms per round (normals + Poisson):", ", ".join(f"{p['ms']['normals']:.0f} + {p['ms']['poisson']:.0f}" for p in poisson))
print()
base = rows[0][1]
print("| method | ms per frame set, median / p95 | × faster than Open3D 10 mm | `zipfusion bench` ms, median / p95 | accuracy mean / p95 mm | completeness % | area ratio | components (large) | triangles | peak RSS MiB |")
print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
for label, med, p95, prep, b, q, rss in rows:
    ms = f"{med:.1f}" + ("" if p95 is None else f" / {p95:.1f}") + (f" (+{prep:.0f} prep.)" if prep is not None else "")
    bs = "" if b is None else f"{b['median']:.1f} / {b['p95']:.1f}"
    print(f"| {label} | {ms} | {base / med:.2f} | {bs} | {q['accuracy_mean_mm']:.2f} / {q['accuracy_p95_mm']:.2f} | "
          f"{100 * q['completeness']:.1f} | {q['area_ratio']:.2f} | {q['components']:.0f} ({q['large_components']:.1f}) | {q['triangles']:.0f} | "
          f"{'' if rss is None else f'{rss:.0f}'} |")
EOF
