#!/usr/bin/env bash
# Runs every libFuzzer target built in FUZZ_DIR (make fuzz) for SECONDS each, from the seeds in
# fuzz/corpus/NAME. What libFuzzer adds to the corpus goes to FUZZ_DIR/corpus/NAME (the checked-in
# seeds are not touched); a finding is written to FUZZ_DIR/findings/NAME/ and fails the script.
# Copy a finding into fuzz/corpus/NAME once it is fixed: `make test` then replays it for good.
set -euo pipefail
fuzz_dir=${1:?usage: fuzz.sh FUZZ_DIR SECONDS}
seconds=${2:?usage: fuzz.sh FUZZ_DIR SECONDS}
source_dir=$(cd "$(dirname "$0")/.." && pwd)

failed=()
for target in "$fuzz_dir"/zf_fuzz_*; do
  [ -x "$target" ] || continue
  name=${target##*/zf_fuzz_}
  corpus="$fuzz_dir/corpus/$name"
  findings="$fuzz_dir/findings/$name"
  mkdir -p "$corpus" "$findings"
  # A fakenect frame is 614 417 or 921 615 bytes: its seeds are only useful whole.
  max_len=65536
  if [ "$name" = fakenect ]; then max_len=1000000; fi
  echo "fuzz: $name for ${seconds} s"
  if ! "$target" "$corpus" "$source_dir/fuzz/corpus/$name" \
      -max_total_time="$seconds" -max_len="$max_len" -timeout=10 -rss_limit_mb=4096 \
      -artifact_prefix="$findings/" -print_final_stats=1 >"$fuzz_dir/$name.log" 2>&1; then
    failed+=("$name")
    echo "fuzz: $name FAILED; log $fuzz_dir/$name.log, input in $findings/"
  fi
  grep -E "^stat::number_of_executed_units|^stat::new_units_added|^stat::peak_rss_mb" "$fuzz_dir/$name.log" | sed "s/^/fuzz: $name: /" || true
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]}"
  exit 1
fi
echo "fuzz: no findings"
