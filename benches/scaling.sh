#!/usr/bin/env bash
# Thread scaling of the two parallel jobs, on the machine it runs on: a trace of 4·10⁶ lamp rays
# and a dataset of 96 × 96 objects (3 schemes × 3 ratios), each at 1, 2, 4, … threads up to the
# core count, wall time from the command's own start to its end. Usage:
#   benches/scaling.sh [SPIBENCH] [OUT]      (default: target/release/spibench, /tmp/spibench-scaling)
# It prints one line per job and thread count: seconds, rays/s or samples/s, and the speed-up
# against one thread. Results are bit-identical for every thread count; the script checks it.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/spibench}
out=${2:-/tmp/spibench-scaling}
samples=${SAMPLES:-4000}
rays=${RAYS:-4000000}
rm -rf "$out" && mkdir -p "$out"
cores=$(nproc)
threads=(1)
t=2
while [ "$t" -le "$cores" ]; do threads+=("$t"); t=$((t * 2)); done
cat > "$out/spec.ron" <<SPEC
Dataset(
    bench: "$PWD/scenes/paper_bench.ron",
    kernel: (rays: 200000, seed: 1, grid_px: (96, 96), field_mm: (7.88, 7.88)),
    objects: TestImages(names: ["astronaut", "coffee"], rule: RandomCrop),
    acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm, Traditional], ratios: [0.1, 0.25, 0.5]),
    seed: 7,
    samples: $samples,
    shard_samples: 250,
)
SPEC
now() { date +%s.%N; }
echo "cores: $cores; binary: $bin"
base_trace=; base_data=
for t in "${threads[@]}"; do
    s=$(now)
    "$bin" trace scenes/paper_bench.ron --rays "$rays" --threads "$t" --out "$out/trace$t" -q >/dev/null
    dt=$(awk -v a="$(now)" -v b="$s" 'BEGIN { print a - b }')
    base_trace=${base_trace:-$dt}
    awk -v t="$t" -v dt="$dt" -v n="$rays" -v b="$base_trace" \
        'BEGIN { printf "trace   %2d threads: %7.2f s  %9.0f rays/s  speed-up %5.2f\n", t, dt, n / dt, b / dt }'
    cmp -s "$out/trace1/maps.exr" "$out/trace$t/maps.exr" || echo "trace: maps differ at $t threads"
done
for t in "${threads[@]}"; do
    s=$(now)
    "$bin" dataset "$out/spec.ron" --threads "$t" --out "$out/data$t" -q >/dev/null
    dt=$(awk -v a="$(now)" -v b="$s" 'BEGIN { print a - b }')
    base_data=${base_data:-$dt}
    awk -v t="$t" -v dt="$dt" -v n="$samples" -v b="$base_data" \
        'BEGIN { printf "dataset %2d threads: %7.2f s  %9.1f samples/s  speed-up %5.2f\n", t, dt, n / dt, b / dt }'
    diff -rq "$out/data1" "$out/data$t" -x manifest.json >/dev/null || echo "dataset: arrays differ at $t threads"
done
