#!/usr/bin/env bash
# The tolerance budget of the shipped 27-tolerance file on the paper bench at the default rays
# (200 000 per trace), Y = 0.95, C = 0.95, 300 trials per confirmation: its wall time against
# the 15-minute goal of issue 50, on THREADS threads (2 by default), and, as the baseline in
# the same run, a plain Monte Carlo of the shipped file (`spibench tolerance --trials BASE`),
# so that the budget's time reads as so many Monte Carlo trials' worth.
#
#   benches/budget.sh [BIN]        (BIN defaults to target/release/spibench)
#
# Printed: the load average before and after (other work on the machine slows both runs
# alike), each run's wall time, the trials the budget traced (baseline and rounds), its time per
# traced trial against the Monte Carlo's, its outcome (the geometric-mean scales of the joint
# and one-at-a-time budgets, their confirmed yields), and whether it stayed under 15 minutes.
# Environment: THREADS (2), RAYS (the default of `tolerance`), TRIALS (300), BASE (60),
# OUT (work folder, default /tmp/spibench-budget-bench, emptied first). Needs python3 (JSON).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/spibench}
[ -x "$bin" ] || { echo "budget: $bin is not an executable (cargo build --release)" >&2; exit 2; }
threads=${THREADS:-2}
trials=${TRIALS:-300}
base=${BASE:-60}
out=${OUT:-/tmp/spibench-budget-bench}
rays=()
[ -z "${RAYS:-}" ] || rays=(--rays "$RAYS")
rm -rf "$out" && mkdir -p "$out"
tol=scenes/tolerances/paper_bench.ron
now() { date +%s.%N; }
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; $threads threads"
t0=$(now)
"$bin" --threads "$threads" tolerance --tolerances "$tol" --trials "$base" "${rays[@]}" \
    --out "$out/mc" >"$out/mc.log" 2>&1 || { cat "$out/mc.log"; exit 1; }
t1=$(now)
"$bin" --threads "$threads" tolerance --tolerances "$tol" --budget --target-yield 0.95 \
    --trials "$trials" "${rays[@]}" --out "$out/budget" >"$out/budget.log" 2>&1 \
    || { cat "$out/budget.log"; exit 1; }
t2=$(now)
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
python3 - "$out" "$t0" "$t1" "$t2" "$base" <<'EOF'
import json, sys
out, t0, t1, t2, base = sys.argv[1], *map(float, sys.argv[2:5]), int(sys.argv[5])
s = json.load(open(f"{out}/budget/summary.json"))
traced = s["trials"] * (len(s["rounds"]) + 1)
mc, bud = t1 - t0, t2 - t1
print(f"rays per trace {s['rays']}; Monte Carlo of {base} trials: {mc:.0f} s "
      f"({mc / base:.2f} s per trial, sensitivity table included)")
print(f"budget: {bud:.0f} s ({bud / 60:.1f} min), {traced} trials traced "
      f"({bud / traced:.2f} s per trial, the 54-end sensitivity table included), "
      f"= {bud / (mc / base):.0f} Monte Carlo trials' time")
for name in ("joint", "baseline"):
    f = s[name]
    c = f["confirmation"] or {}
    print(f"  {name}: geometric-mean scale {f['geometric_mean_scale']:.4f}, total cost "
          f"{f['total_cost']:.2f}, confirmed {c.get('passed')}/{c.get('trials')} "
          f"(lower bound {c.get('lower_bound', float('nan')):.4f})")
print(f"  reached {s['reached']}; stop: {s['stop']}")
print("under 15 minutes:", "yes" if bud < 900 else "NO")
EOF
