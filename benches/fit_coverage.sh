#!/usr/bin/env bash
# Coverage of `spibench fit` on benches with known misalignments (issue 48, "Recovery on known
# benches"). Each bench is the paper bench at 16 × 16 units with 2 to 4 variables moved (arm
# lens decentres and tilts, diode decentres, the DMD's tilt) to values where they change the
# light; its records come from `run --scope-record` (noise on) traced with MEAS_RAYS rays, taken
# in by `intake`, and `fit` starts from the nominal bench with FIT_RAYS rays.
#
#   benches/fit_coverage.sh [BIN]        (BIN defaults to target/release/spibench)
#
# Printed per bench: each variable's true value, fitted value ± standard error and whether the
# 95 % interval (value ± 1.96·stderr) holds the truth, or for an unidentified variable whether
# its range of equally good values does; χ²/dof against the expected value and its band from
# the fit's own noise model (summary.json's chi2_expected, chi2_band_per_dof) with the measured
# bench's own trace noise added (it adds FIT_RAYS/MEAS_RAYS of the trace part: a real bench
# has none); the wall time. Then the coverage over all identified variables, the RMS and
# median of |fitted − true|/stderr over them, the count of
# χ²/dof inside their bands, and the machine load (other builds may share the cores).
# Environment: FIT_RAYS (30000), MEAS_RAYS (300000), THREADS (2), OUT (work folder, default
# /tmp/spibench-fit-coverage, emptied first), ONLY (a space-separated list of bench numbers),
# SEED (0: added to the measured run's seed 100 + k and the fit's 200 + k, for repeats).
# Needs python3 (JSON).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/spibench}
[ -x "$bin" ] || { echo "fit_coverage: $bin is not an executable" >&2; exit 2; }
bin=$(realpath "$bin")
fit_rays=${FIT_RAYS:-30000}
meas_rays=${MEAS_RAYS:-300000}
threads=${THREADS:-2}
seed=${SEED:-0}
out=${OUT:-/tmp/spibench-fit-coverage}
rm -rf "$out" && mkdir -p "$out"
export RAYON_NUM_THREADS=$threads

# The paper bench at 16 × 16 units (as in docs/guide/11-fitting.md).
sed -e 's/units_across: 48, units_down: 48, mirrors_per_unit: 12/units_across: 16, units_down: 16, mirrors_per_unit: 36/' \
    -e '$ s/^)$/    run: (rays: 30000, sampling_ratios: [0.25, 1.0]),\n)/' scenes/paper_bench.ron \
    >"$out/small.ron"

lens_p=arm_plus_lens.decenter_mm
lens_m=arm_minus_lens.decenter_mm
# Each bench: "PATH=TRUE@LO:HI ..." (the bounds hold the nominal value).
benches=(
    "$lens_p.x=1.5@-3:3 detectors.plus.decenter_mm.x=0.1@-1:1"
    "$lens_p.x=-1.2@-3:3 dmd.tilt_deg=12.3@11:13"
    "$lens_m.x=1.4@-3:3 $lens_p.x=1.0@-3:3"
    "$lens_m.x=-1.3@-3:3 detectors.minus.decenter_mm.x=0.4@-1:1 dmd.tilt_deg=11.8@11:13"
    "$lens_p.y=1.4@-3:3 $lens_p.x=0.8@-3:3"
    "$lens_p.x=1.6@-3:3 $lens_m.x=-1.1@-3:3 detectors.plus.decenter_mm.x=-0.2@-1:1"
    "dmd.tilt_deg=12.25@11:13 detectors.plus.decenter_mm.x=0.3@-1:1 $lens_p.x=1.3@-3:3"
    "$lens_p.x=1.2@-3:3 $lens_m.x=1.5@-3:3 detectors.plus.decenter_mm.x=0.2@-1:1 detectors.minus.decenter_mm.x=-0.3@-1:1"
    "arm_minus_lens.tilt_deg.x=3@-6:6 $lens_m.x=1.4@-3:3"
    "$lens_p.x=-1.6@-3:3 $lens_p.y=0.9@-3:3 dmd.tilt_deg=11.75@11:13 detectors.minus.decenter_mm.x=0.25@-1:1"
)
read -r -a only <<<"${ONLY:-$(seq -s ' ' 1 ${#benches[@]})}"
start=$(date +%s)
echo "fit coverage: $bin, fit $fit_rays rays, measured $meas_rays rays, $threads threads, seed +$seed"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"
for k in "${only[@]}"; do
    spec=${benches[$((k - 1))]}
    dir="$out/bench$k"
    mkdir -p "$dir"
    sets=()
    frees=()
    for v in $spec; do
        path=${v%%=*}
        rest=${v#*=}
        sets+=(--set "$path=${rest%%@*}")
        frees+=(--free "$path=${rest#*@}")
    done
    t0=$(date +%s.%N)
    "$bin" run "$out/small.ron" "${sets[@]}" --rays "$meas_rays" --seed $((100 + k + seed)) \
        --scope-record --out "$dir/run" -q >"$dir/run.log" 2>&1
    "$bin" intake "$dir/run/scope" --bench "$dir/run/bench.ron" --out "$dir/intake" -q \
        >"$dir/intake.log" 2>&1
    rm -rf "$dir/run/scope"
    "$bin" fit "$out/small.ron" --measured "$dir/intake" "${frees[@]}" --rays "$fit_rays" \
        --seed $((200 + k + seed)) --out "$dir/fit" -q >"$dir/fit.log" 2>&1 ||
        { echo "bench $k: fit failed: $(tail -1 "$dir/fit.log")"; continue; }
    t1=$(date +%s.%N)
    python3 - "$dir/fit/summary.json" "$spec" "$k" "$(echo "$t1 - $t0" | bc)" \
        "$fit_rays" "$meas_rays" <<'EOF' | tee -a "$out/rows.txt"
import json, sys
s = json.load(open(sys.argv[1]))
spec, k, wall = sys.argv[2].split(), sys.argv[3], float(sys.argv[4])
fit_rays, meas_rays = float(sys.argv[5]), float(sys.argv[6])
truth = {v.split("=")[0]: float(v.split("=")[1].split("@")[0]) for v in spec}
e = s["chi2_expected"]
dof = s["dof"]
# The measured bench's own trace adds fit_rays/meas_rays of the trace part (a real bench: 0).
mean = (e["measurement"] + e["trace"] * (1 + fit_rays / meas_rays)) / dof
lo, hi = mean - 2 * e["sd"] / dof, mean + 2 * e["sd"] / dof
c = s["chi2_per_dof"]
inband = lo <= c <= hi
print(f"BENCH {k} chi2/dof {c:.3f} expected {mean:.3f} band [{lo:.3f}, {hi:.3f}] "
      f"{'in' if inband else 'OUT'} wall {wall:.0f} s evaluations {s['evaluations']}")
for v in s["variables"]:
    t = truth[v["path"]]
    if v["identified"]:
        ok = abs(v["value"] - t) <= 1.96 * v["stderr"]
        print(f"VAR {v['path']} true {t} fitted {v['value']:.4f} ± {v['stderr']:.4f} "
              f"z {(v['value'] - t) / v['stderr']:+.2f} {'covered' if ok else 'MISSED'}")
    else:
        ok = v["range_lo"] <= t <= v["range_hi"]
        print(f"UNID {v['path']} true {t} range [{v['range_lo']:.3f}, {v['range_hi']:.3f}] "
              f"{'inside' if ok else 'OUTSIDE'}")
EOF
done
end=$(date +%s)
python3 - "$out/rows.txt" <<'EOF'
import sys
rows = open(sys.argv[1]).read().splitlines()
var = [r for r in rows if r.startswith("VAR")]
unid = [r for r in rows if r.startswith("UNID")]
ben = [r for r in rows if r.startswith("BENCH")]
cov = sum(r.endswith("covered") for r in var)
print(f"coverage of the 95 % intervals: {cov} of {len(var)} identified variables "
      f"({100 * cov / max(1, len(var)):.0f} %)")
# The actual error over the reported one: |z| = |fitted − true|/stderr; RMS 1 when the
# standard errors are honest (a median |z| of 0.67 for Gaussian errors).
zs = sorted(abs(float(r.split(" z ")[1].split()[0])) for r in var)
if zs:
    rms = (sum(z * z for z in zs) / len(zs)) ** 0.5
    print(f"|error|/stderr over the identified variables: RMS {rms:.2f}, median "
          f"{zs[len(zs) // 2]:.2f} (1.00 and 0.67 for honest Gaussian errors)")
print(f"unidentified: {sum(r.endswith('inside') for r in unid)} of {len(unid)} with the truth "
      "inside their range")
print(f"chi2/dof inside its band: {sum(' in ' in r for r in ben)} of {len(ben)} benches")
EOF
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg); total $((end - start)) s"
