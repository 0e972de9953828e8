#!/usr/bin/env bash
# Runs the test suite built with ThreadSanitizer (make tsan) in TSAN_DIR; any data race,
# lock-order inversion or misuse of a mutex that TSan reports fails its test. Reports go to the
# test's output. scripts/tsan.supp lists what is suppressed, each with its reason.
set -euo pipefail
tsan_dir=${1:?usage: tsan.sh TSAN_DIR [ctest arguments]}
shift
source_dir=$(cd "$(dirname "$0")/.." && pwd)
# memory_test checks glibc's malloc settings (keep_freed_memory), which TSan's own allocator
# replaces; the fuzz corpora replay single-threaded decoders, which `make test` covers.
exclude='^(memory_test|fuzz_corpus_.*)$'
export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$source_dir/scripts/tsan.supp ${TSAN_OPTIONS:-}"
cd "$tsan_dir"
ctest --output-on-failure --timeout 1800 -E "$exclude" "$@"
