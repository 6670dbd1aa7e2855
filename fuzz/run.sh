#!/usr/bin/env bash
# Builds the fuzz targets with libFuzzer and AddressSanitizer (nightly Rust,
# as `cargo fuzz build` does) and runs each for SECONDS (default 30) from
# the generated seeds plus the corpus kept so far in fuzz/corpus/<target>.
#
#   fuzz/run.sh [SECONDS] [TARGET...]
#
# A crash leaves its input in fuzz/artifacts/<target>/ and fails the script.
# Needs a nightly toolchain (`rustup toolchain list`); without one it says so
# and exits 0, so that CI on a machine with only stable Rust still passes.
set -euo pipefail
cd "$(dirname "$0")"
seconds=${1:-30}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(scene_toml formula obj_mtl ply gltf)

if ! cargo +nightly --version >/dev/null 2>&1; then
    echo "fuzz: no nightly toolchain here; skipping the fuzz run (see fuzz/README.md)"
    exit 0
fi
if ! command -v c++ >/dev/null 2>&1 && ! command -v clang++ >/dev/null 2>&1; then
    echo "fuzz: no C++ compiler here to build libFuzzer; skipping the fuzz run"
    exit 0
fi
triple=$(rustc -vV | sed -n 's/^host: //p')
# The flags cargo-fuzz passes: coverage counters and comparisons for
# libFuzzer, AddressSanitizer, debug assertions and overflow checks.
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Zsanitizer=address \
-Cdebug-assertions -Coverflow-checks"
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=0}
cargo +nightly build --release --target "$triple" --bins
bin=target/$triple/release
"$bin/seeds"
status=0
for t in "${targets[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    echo "fuzz: $t for ${seconds}s"
    # -rss_limit_mb: a loader that allocates past 2 GB is a failure;
    # -timeout: an input taking over 20 s is a hang.
    if ! "$bin/$t" "corpus/$t" "seeds/$t" -max_total_time="$seconds" -timeout=20 \
        -rss_limit_mb=2048 -malloc_limit_mb=2048 -artifact_prefix="artifacts/$t/" \
        -print_final_stats=1 2>"artifacts/$t.log"; then
        echo "fuzz: $t FAILED; last lines of artifacts/$t.log:"
        tail -n 40 "artifacts/$t.log"
        status=1
    else
        grep -E "^(stat::number_of_executed_units|stat::new_units_added)" "artifacts/$t.log" | sed "s/^/fuzz: $t: /" || true
    fi
done
exit $status
