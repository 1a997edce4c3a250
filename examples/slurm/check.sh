#!/usr/bin/env bash
# Runs the job arrays of examples/slurm/ on the Slurm that sbatch reaches (single-node.sh starts
# one) and checks their merged outputs against single-process runs of the same inputs:
#
#   examples/slurm/check.sh [WORK]      # WORK: a folder every node sees (default target/slurm-check)
#
# - a small dataset as a 4-task array (--array=0-3) and its dependent merge: every file of the
#   merged dataset, the .npy arrays, spec.ron and bench.ron, equals the single-process run's byte
#   for byte; manifest.json too, less its provenance "command" and "merged_from" (the command
#   lines differ, and the merge records the shard folders it read);
# - a tolerance Monte Carlo as a 3-task array numbered from 1 (--array=1-3) and its merge: every
#   file equals the single-process run's byte for byte (trials, sensitivity table, CSV, SVG, PNG,
#   HTML report, PDF figures), except summary.json, compared less its provenance "command" and
#   "inputs" (the merge's inputs are the shards' trials.ron).
#
# The jobs ask for one core each; the binary is $SPIBENCH, else `spibench` on PATH.
set -euo pipefail
cd "$(dirname "$0")/../.."
REPO=$PWD
WORK=$(realpath -m "${1:-target/slurm-check}")
SPIBENCH=$(command -v "${SPIBENCH:-spibench}") ||
    { echo "check.sh: no spibench binary (set SPIBENCH or put spibench on PATH)" >&2; exit 1; }
export SPIBENCH
command -v sbatch >/dev/null || { echo "check.sh: sbatch is not on PATH" >&2; exit 1; }
say() { echo "check: $*" >&2; }
start=$(date +%s)

rm -rf "$WORK" && mkdir -p "$WORK/log" && cd "$WORK"
cat >spec.ron <<SPEC
Dataset(
    bench: "$REPO/scenes/paper_bench.ron",
    kernel: (rays: 8192, seed: 1, grid_px: (24, 24), field_mm: (7.88, 7.88)),
    objects: TestImages(names: ["astronaut", "coffee"], rule: RandomCrop),
    acquisition: (schemes: [SecondaryComplementaryBalancing, DoubleArm], ratios: [0.05, 0.25]),
    seed: 7,
    samples: 24,
    shard_samples: 4,
)
SPEC
tolerance_args=(--tolerances "$REPO/scenes/tolerances/paper_bench.ron" --rays 4096 --trials 9)

# The arrays and their merges, submitted as a user would (examples/slurm/*.sbatch headers).
sb() { sbatch --parsable --cpus-per-task=1 "$@"; }
ds=$(sb --array=0-3 --output=log/%x-%A_%a.out "$REPO/examples/slurm/dataset.sbatch" spec.ron dataset)
ds_merge=$(sb --dependency=afterok:"$ds" --kill-on-invalid-dep=yes --output=log/%x-merge-%j.out \
    "$REPO/examples/slurm/dataset.sbatch" --merge dataset 4)
tol=$(sb --array=1-3 --output=log/%x-%A_%a.out "$REPO/examples/slurm/tolerance.sbatch" \
    tolerance "${tolerance_args[@]}")
tol_merge=$(sb --dependency=afterok:"$tol" --kill-on-invalid-dep=yes --output=log/%x-merge-%j.out \
    "$REPO/examples/slurm/tolerance.sbatch" --merge tolerance 3)
jobs="$ds,$ds_merge,$tol,$tol_merge"
say "submitted dataset array $ds (merge $ds_merge), tolerance array $tol (merge $tol_merge)"

# The single-process runs, meanwhile, outside Slurm.
"$SPIBENCH" dataset spec.ron --out dataset-single -q >log/dataset-single.out 2>&1
"$SPIBENCH" tolerance "${tolerance_args[@]}" --out tolerance-single -q >log/tolerance-single.out 2>&1

for ((t = 0; t < 600; t += 2)); do
    [ -z "$(squeue -h -j "$jobs" -o %i 2>/dev/null)" ] && break
    sleep 2
done
states=$(for j in ${jobs//,/ }; do scontrol -o show job "$j"; done |
    sed -nE 's/^JobId=([0-9]+) .*JobState=([A-Z_]+).*/\1 \2/p')
echo "$states" | sed 's/^/    job /' >&2
if grep -qv ' COMPLETED$' <<<"$states"; then
    tail -n 20 log/*.out >&2
    say "FAILED: a job did not complete (logs in $WORK/log)"
    exit 1
fi
say "jobs done in $(($(date +%s) - start)) s"

fail=0
files() { (cd "$1" && find . -type f | LC_ALL=C sort); }
same_files() {
    diff <(files "$1") <(files "$2") >&2 || { say "FAILED: $1 and $2 hold different files"; fail=1; }
}
# The JSON file less the provenance fields named (they are expected to differ), re-printed with
# sorted keys so that the comparison does not hang on the commas around a removed field.
drop() {
    python3 - "$@" <<'PY'
import json, sys
doc = json.load(open(sys.argv[1]))
for field in sys.argv[2:]:
    doc["provenance"].pop(field, None)
print(json.dumps(doc, indent=1, sort_keys=True))
PY
}
# Whether the two files (of $f) are equal, compared as $3 says.
compare() {
    if ! cmp -s "$1" "$2"; then
        say "FAILED: $f of the merged run differs from the single-process run's ($3)"
        fail=1
    fi
}

same_files dataset-single dataset
n=0
while read -r f; do
    if [ "$f" = ./manifest.json ]; then
        compare <(drop dataset-single/"$f" command merged_from) <(drop dataset/"$f" command merged_from) \
            "less provenance.command and provenance.merged_from"
    else
        compare dataset-single/"$f" dataset/"$f" bytes
    fi
    n=$((n + 1))
done < <(files dataset-single)
say "dataset: $n files of the merged array run checked against the single-process run"

same_files tolerance-single tolerance
n=0
while read -r f; do
    case $f in
    ./summary.json)
        compare <(drop tolerance-single/"$f" command inputs) <(drop tolerance/"$f" command inputs) \
            "less provenance.command and provenance.inputs" ;;
    *) compare tolerance-single/"$f" tolerance/"$f" bytes ;;
    esac
    n=$((n + 1))
done < <(files tolerance-single)
say "tolerance: $n files of the merged array run checked against the single-process run"

[ "$fail" = 0 ] || { say "FAILED (outputs in $WORK)"; exit 1; }
say "passed in $(($(date +%s) - start)) s"
