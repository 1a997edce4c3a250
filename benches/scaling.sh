#!/usr/bin/env bash
# Thread scaling of the parallel jobs on the machine it runs on: a trace of RAYS lamp rays, a
# dataset of SAMPLES 96 × 96 objects (3 schemes × 3 ratios, a kernel of 200 000 rays) and, with
# JOBS=run, the default `spibench run` (rate column: runs per second), each at 1, 2, 4, …
# threads up to the core count; wall time of the whole command (kernel trace, setup and writing
# included). Runs unattended and prints one compact table.
#
#   benches/scaling.sh [BIN …]          (default: target/release/spibench)
#
# Several binaries (say the commit before a change and after it) run in turn on the same machine,
# so their figures compare; each is labelled by its position (b1, b2, …) and listed first.
# Environment: OUT (work folder, default /tmp/spibench-scaling, emptied first), SAMPLES (4000),
# RAYS (4000000), THREADS (default "1 2 4 … cores"), JOBS ("trace dataset"; either alone, "run", or
# "processes" and "dataset-processes" for the machine's own ceiling, below), PROCESS_RAYS
# (1000000).
#
# Columns: seconds; rays/s or samples/s; speed-up against the first thread count (×1, normally
# 1 thread) and against 2 threads (×2, the figure issue 26 states for the dataset); `cpu`, the
# command's user + system CPU seconds, `sys` the system part, and `cpu×`, the CPU against the
# first thread count's (above 1: the same work costs more CPU on more threads, contention or a
# slower clock rather than idle threads); `out%`, the share of the dataset command's
# own time spent outside its parallel sample loops (printed by binaries that report it, else
# "-"), and below a dataset row where its shards' writing went (the arrays' files, the
# manifest, how long the sample loops waited for it, and by how long they outlasted their last
# samples: a loop's thread held by other work such as a file's writing); `same`, whether the outputs equal the first run's
# of that binary byte for byte (the dataset's arrays, and its manifest less the command line)
# and, for binaries after the first, whether the dataset's arrays equal b1's. Exit status 1 if any output differs. A run's output
# folder is removed once compared (only each binary's first is kept), so that a large dataset
# does not fill the disk or the page cache.
# Budget: with the defaults one binary takes about 2 minutes on 16 cores (most of it at 1 thread).
set -euo pipefail
cd "$(dirname "$0")/.."
bins=("$@")
[ ${#bins[@]} -gt 0 ] || bins=(target/release/spibench)
out=${OUT:-/tmp/spibench-scaling}
samples=${SAMPLES:-4000}
rays=${RAYS:-4000000}
jobs=${JOBS:-trace dataset}
cores=$(nproc)
if [ -n "${THREADS:-}" ]; then
    read -r -a threads <<<"$THREADS"
else
    threads=(1)
    t=2
    while [ "$t" -le "$cores" ]; do threads+=("$t"); t=$((t * 2)); done
    [ "${threads[-1]}" -eq "$cores" ] || [ "$cores" -eq 1 ] || threads+=("$cores")
fi
for b in "${bins[@]}"; do
    [ -x "$b" ] || { echo "scaling: $b is not an executable" >&2; exit 2; }
done
rm -rf "$out" && mkdir -p "$out"
cat >"$out/spec.ron" <<SPEC
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
# A dataset manifest as sorted JSON, less the keys named (dotted paths), for comparisons.
manifest_less() {
    python3 - "$@" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
for key in sys.argv[2:]:
    d = m
    *head, last = key.split(".")
    for h in head:
        d = d.get(h, {})
    d.pop(last, None)
print(json.dumps(m, sort_keys=True))
PY
}
have_python=$(command -v python3 >/dev/null && echo 1 || echo 0)
failed=0
echo "cores: $cores; threads: ${threads[*]}; trace $rays rays; dataset $samples samples"
for i in "${!bins[@]}"; do echo "b$((i + 1)): ${bins[$i]} ($("${bins[$i]}" --version 2>/dev/null || echo '?'))"; done
[ -z "$(echo " $jobs " | sed 's/ processes / /g; s/ dataset-processes / /g' | tr -d ' ')" ] ||
    printf '%-8s %-3s %4s %8s %12s %6s %6s %7s %5s %5s %5s %s\n' job bin thr s rate/s x1 x2 cpu sys cpu× out% same
for job in $jobs; do
    case $job in processes | dataset-processes) continue ;; esac
    for i in "${!bins[@]}"; do
        bin=${bins[$i]}
        tag=b$((i + 1))
        base1=
        base2=
        cpu1=
        for t in "${threads[@]}"; do
            dir="$out/$job-$tag-$t"
            case $job in
            trace)
                n=$rays
                cmd=("$bin" trace scenes/paper_bench.ron --rays "$rays" --threads "$t" --out "$dir" -q)
                ;;
            dataset)
                n=$samples
                cmd=("$bin" dataset "$out/spec.ron" --threads "$t" --out "$dir")
                ;;
            run)
                # The default run (the paper's bench, every scheme and ratio): one job a row.
                n=1
                cmd=("$bin" run --threads "$t" --out "$dir" -q)
                ;;
            *) echo "scaling: unknown job $job (JOBS: trace, dataset, run, processes, dataset-processes)" >&2; exit 2 ;;
            esac
            s=$(now)
            # bash's `time` keyword: the child's user and system CPU seconds, on any machine.
            { TIMEFORMAT='%U %S'; time "${cmd[@]}" >"$dir.log" 2>&1; } 2>"$dir.cpu" || {
                echo "scaling: $bin $job failed at $t threads:" >&2
                tail -5 "$dir.log" >&2
                exit 1
            }
            dt=$(awk -v a="$(now)" -v b="$s" 'BEGIN { print a - b }')
            cpu=$(awk '{ print $1 + $2 }' "$dir.cpu")
            sys=$(awk '{ print $2 }' "$dir.cpu")
            cpu1=${cpu1:-$cpu}
            base1=${base1:-$dt}
            [ "$t" != 2 ] || base2=$dt
            pct=$(grep -o '[0-9.]* % of the' "$dir.log" | head -1 | cut -d' ' -f1 || true)
            same=ok
            first="$out/$job-$tag-${threads[0]}"
            if [ "$job" = trace ]; then
                cmp -s "$first/maps.exr" "$dir/maps.exr" || same=DIFFERS
            elif [ "$job" = run ]; then
                # Everything but the provenance (summary.json) and the stage times.
                diff -rq -x summary.json -x timings.json -x report.html "$first" "$dir" >/dev/null ||
                    same=DIFFERS
            else
                diff -rq -x manifest.json "$first" "$dir" >/dev/null || same=DIFFERS
                if [ "$have_python" = 1 ] && [ "$same" = ok ] &&
                    [ "$(manifest_less "$first/manifest.json" provenance.command)" != \
                      "$(manifest_less "$dir/manifest.json" provenance.command)" ]; then
                    same=MANIFEST-DIFFERS
                fi
                if [ "$i" -gt 0 ] && [ "$t" = "${threads[0]}" ]; then
                    diff -rq -x manifest.json "$out/$job-b1-$t" "$dir" >/dev/null &&
                        same="$same,=b1" || same="$same,ARRAYS-DIFFER-FROM-b1"
                fi
            fi
            case $same in *DIFF*) failed=1 ;; esac
            [ "$dir" = "$first" ] || rm -rf "$dir"
            awk -v job="$job" -v tag="$tag" -v t="$t" -v dt="$dt" -v n="$n" -v b1="$base1" \
                -v b2="$base2" -v cpu="$cpu" -v sys="$sys" -v cpu1="$cpu1" -v pct="${pct:--}" -v same="$same" 'BEGIN {
                    x2 = b2 == "" ? "-" : sprintf("%.2f", b2 / dt)
                    printf "%-8s %-3s %4d %8.2f %12.1f %6.2f %6s %7.1f %5.1f %5.2f %5s %s\n",
                        job, tag, t, dt, n / dt, b1 / dt, x2, cpu, sys, cpu / cpu1, pct, same }'
            # Where a dataset's shard writing went (binaries that report it).
            grep -h '^shard writing' "$dir.log" 2>/dev/null | sed 's/^/    /' || true
        done
    done
done
# The machine's own ceiling: t single-thread traces of PROCESS_RAYS rays run side by side as
# separate processes (nothing shared but the machine), each timed; their mean and longest time
# against one alone (the first thread count's run), and then one process tracing t times the
# rays on t threads (`threads`: its time against the processes' mean; near 1 or below, the
# threads lose nothing). The binary is the last one named. Above 1, t busy cores slow each
# other's work (shared caches, memory bandwidth, clock, a virtual machine's neighbours), which
# no change to spibench removes. `dataset-processes` does the same for the dataset spec: t
# single-thread processes each making a block of its shards (`--shard k/t`) against one process
# on t threads, comparing the seconds each spends in its sample loops and commits (the summary
# line's figure; the kernel's trace, which every process repeats, left out).
if [[ " $jobs " == *" processes "* ]]; then
    prays=${PROCESS_RAYS:-1000000}
    bin=${bins[-1]}
    echo "processes: $bin, single-thread traces of $prays rays side by side"
    printf '%-10s %4s %8s %8s %7s %7s\n' job procs mean_s max_s mean× max×
    alone=
    for t in "${threads[@]}"; do
        for k in $(seq 1 "$t"); do
            (
                TIMEFORMAT=%R
                { time "$bin" trace scenes/paper_bench.ron --rays "$prays" --threads 1 \
                    --out "$out/proc-$t-$k" -q >"$out/proc-$t-$k.log" 2>&1; } 2>"$out/proc-$t-$k.wall"
            ) &
        done
        wait
        read -r mean max < <(cat "$out"/proc-"$t"-*.wall |
            awk '{ s += $1; if ($1 > m) m = $1 } END { print s / NR, m }')
        alone=${alone:-$mean}
        rm -rf "$out"/proc-"$t"-*
        awk -v t="$t" -v mean="$mean" -v max="$max" -v a="$alone" 'BEGIN {
            printf "%-10s %4d %8.2f %8.2f %7.2f %7.2f\n", "processes", t, mean, max, mean / a, max / a }'
        [ "$t" -gt 1 ] || continue
        s=$(now)
        "$bin" trace scenes/paper_bench.ron --rays $((prays * t)) --threads "$t" \
            --out "$out/threads-$t" -q >"$out/threads-$t.log" 2>&1
        dt=$(awk -v a="$(now)" -v b="$s" 'BEGIN { print a - b }')
        rm -rf "$out/threads-$t"
        awk -v t="$t" -v dt="$dt" -v mean="$mean" -v a="$alone" 'BEGIN {
            printf "%-10s %4d %8.2f %8s %7.2f %7s  (x%d the rays; against the processes: %.2f)\n",
                "threads", t, dt, "-", dt / a, "-", t, dt / mean }'
    done
fi
if [[ " $jobs " == *" dataset-processes "* ]]; then
    bin=${bins[-1]}
    # The seconds of the summary line: "… of the Z s outside the sample loops".
    loops() { grep -o 'of the [0-9.]* s outside' "$1" | awk '{ print $3 }'; }
    echo "dataset-processes: $bin, $samples samples as t single-thread processes (--shard k/t) or one on t threads"
    printf '%-10s %4s %8s %8s %7s %7s\n' job procs mean_s max_s mean× max×
    alone=
    for t in "${threads[@]}"; do
        for k in $(seq 0 $((t - 1))); do
            "$bin" dataset "$out/spec.ron" --threads 1 --shard "$k/$t" --out "$out/dp-$t-$k" \
                >"$out/dp-$t-$k.log" 2>&1 &
        done
        wait
        read -r mean max < <(for k in $(seq 0 $((t - 1))); do loops "$out/dp-$t-$k.log"; done |
            awk '{ s += $1; if ($1 > m) m = $1 } END { print s / NR, m }')
        # One process's share of the work alone: the t processes' mean against t times that.
        alone=${alone:-$mean}
        rm -rf "$out"/dp-"$t"-*
        awk -v t="$t" -v mean="$mean" -v max="$max" -v a="$alone" -v t0="${threads[0]}" 'BEGIN {
            printf "%-10s %4d %8.2f %8.2f %7.2f %7.2f\n", "processes", t, mean, max,
                mean * t / (a * t0), max * t / (a * t0) }'
        [ "$t" -gt 1 ] || continue
        "$bin" dataset "$out/spec.ron" --threads "$t" --out "$out/dt-$t" >"$out/dt-$t.log" 2>&1
        one=$(loops "$out/dt-$t.log")
        rm -rf "$out/dt-$t"
        awk -v t="$t" -v one="$one" -v mean="$mean" -v max="$max" 'BEGIN {
            printf "%-10s %4d %8.2f %8s %7s %7s  (against the processes: %.2f of their mean, %.2f of the slowest)\n",
                "threads", t, one, "-", "-", "-", one / mean, one / max }'
    done
fi
exit $failed
