#!/usr/bin/env bash
# Time to a given precision on k± for one or several spibench binaries, each with its own bench
# file, traced in turn on the same machine (seed by seed, alternating), so that a binary built
# from an older commit (say the tracer when issue 26 was filed, d000597, built in a worktree)
# and the current one compare in the same run.
#
#   benches/precision.sh BIN[=SCENE] …      (SCENE defaults to scenes/paper_bench.ron)
#
# For each binary: the fixed part of a `trace` (start-up, the chart guide's fit, the output
# files) from the fastest of three runs of 2048 rays; then, per seed, `trace --rays RAYS` timed
# and its relative standard errors of k₊ and k₋ read from summary.json. Printed per binary: the
# mean wall time, the trace's own time (wall less the fixed part), the RMS over the seeds of the
# larger of the two relative errors, and from these the rays and the trace time that reach
# TARGET (the error falls as 1/√rays), and `x_b1`, the first binary's time to TARGET over this one's
# (above 1: this binary gets there faster).
# The relative errors are themselves estimates (batch means), and a few heavy rays move them
# from seed to seed: six seeds or more (the default is eight).
# Environment: RAYS (1000000), SEEDS ("2 3 4 5 6 7 8 9"), THREADS (2), TARGET (1e-3),
# OUT (work folder, default /tmp/spibench-precision, emptied first). Needs python3 (JSON).
set -euo pipefail
cd "$(dirname "$0")/.."
[ $# -gt 0 ] || set -- target/release/spibench
rays=${RAYS:-1000000}
read -r -a seeds <<<"${SEEDS:-2 3 4 5 6 7 8 9}"
threads=${THREADS:-2}
target=${TARGET:-1e-3}
out=${OUT:-/tmp/spibench-precision}
rm -rf "$out" && mkdir -p "$out"
bins=()
scenes=()
for arg in "$@"; do
    bin=${arg%%=*}
    scene=scenes/paper_bench.ron
    [ "$arg" = "$bin" ] || scene=${arg#*=}
    [ -x "$bin" ] || { echo "precision: $bin is not an executable" >&2; exit 2; }
    [ -f "$scene" ] || { echo "precision: $scene is not a file" >&2; exit 2; }
    bins+=("$bin")
    scenes+=("$scene")
done
now() { date +%s.%N; }
# Wall seconds of one trace; its folder is left for the caller to read.
timed_trace() { # bin scene rays seed dir
    local s
    s=$(now)
    "$1" trace "$2" --rays "$3" --seed "$4" --threads "$threads" --out "$5" -q >"$5.log" 2>&1 || {
        echo "precision: $1 failed:" >&2
        tail -5 "$5.log" >&2
        exit 1
    }
    awk -v a="$(now)" -v b="$s" 'BEGIN { print a - b }'
}
# The larger relative standard error of k₊ and k₋ in a summary.json.
rel_se() {
    python3 -c 'import json, sys
d = json.load(open(sys.argv[1]))
print(max(d["k_plus_stderr"] / d["k_plus"], d["k_minus_stderr"] / d["k_minus"]))' "$1/summary.json"
}
echo "rays $rays per trace; seeds ${seeds[*]}; $threads threads; target $target on k±"
fixed=()
for i in "${!bins[@]}"; do
    best=
    for k in 1 2 3; do
        t=$(timed_trace "${bins[$i]}" "${scenes[$i]}" 2048 1 "$out/fixed-$i-$k")
        best=$(awk -v a="$t" -v b="${best:-$t}" 'BEGIN { print (a < b ? a : b) }')
    done
    fixed+=("$best")
    echo "b$((i + 1)): ${bins[$i]} on ${scenes[$i]} ($("${bins[$i]}" --version 2>/dev/null || echo '?')); fixed part ${best} s"
done
for s in "${seeds[@]}"; do
    for i in "${!bins[@]}"; do
        dir="$out/b$i-$s"
        t=$(timed_trace "${bins[$i]}" "${scenes[$i]}" "$rays" "$s" "$dir")
        echo "$t $(rel_se "$dir")" >>"$out/b$i.txt"
        rm -rf "$dir"
    done
done
printf '%-4s %8s %8s %11s %13s %10s %8s\n' bin wall_s trace_s rms_rel_se rays_to_tgt time_to_tgt x_b1
first=
for i in "${!bins[@]}"; do
    line=$(awk -v rays="$rays" -v fixed="${fixed[$i]}" -v tgt="$target" '
        { w += $1; v += $2 * $2; n++ }
        END {
            w /= n; v /= n; tr = w - fixed
            printf "%.3f %.3f %.4e %.0f %.4f", w, tr, sqrt(v), rays * v / (tgt * tgt), tr * v / (tgt * tgt)
        }' "$out/b$i.txt")
    read -r w tr rms nt tt <<<"$line"
    first=${first:-$tt}
    awk -v b="b$((i + 1))" -v w="$w" -v tr="$tr" -v rms="$rms" -v nt="$nt" -v tt="$tt" -v f="$first" 'BEGIN {
        printf "%-4s %8.2f %8.2f %11.3e %13.0f %10.3f %8.2f\n", b, w, tr, rms, nt, tt, f / tt }'
done
