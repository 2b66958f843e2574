#!/usr/bin/env bash
# Fuzz every parser for a bounded time: scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#
# Needs a nightly toolchain and cargo-fuzz (`cargo install cargo-fuzz`). Each target starts
# from the committed seeds in fuzz/corpus/<target>/ and keeps what it discovers in
# fuzz/work/<target>/ (ignored by git). A crash stops that target and leaves the input in
# fuzz/artifacts/<target>/; the script goes on with the other targets and exits non-zero at
# the end. See docs/fuzzing.md for how to turn a finding into a regression case.
set -u
cd "$(dirname "$0")/../fuzz"

SECONDS_PER_TARGET="${1:-60}"
shift || true
TARGETS=("$@")
if [ ${#TARGETS[@]} -eq 0 ]; then
    TARGETS=(ply obj stl scene matrix_market basis splat)
fi
# Keep each run's memory bounded (the readers must not allocate from declared counts).
RSS_LIMIT_MB="${RSS_LIMIT_MB:-2048}"

export CARGO_INCREMENTAL=0
failed=()
for t in "${TARGETS[@]}"; do
    mkdir -p "work/$t"
    echo "=== fuzz $t for ${SECONDS_PER_TARGET} s ==="
    if ! cargo +nightly fuzz run "$t" "work/$t" "corpus/$t" -- \
        -max_total_time="$SECONDS_PER_TARGET" -rss_limit_mb="$RSS_LIMIT_MB" \
        -timeout=10 -print_final_stats=1; then
        failed+=("$t")
    fi
done
if [ ${#failed[@]} -gt 0 ]; then
    echo "findings in: ${failed[*]} (inputs in fuzz/artifacts/)" >&2
    exit 1
fi
echo "no findings in ${TARGETS[*]}"
