"""Exports every validation case with spibench and renders it with Mitsuba 3 (pinned in
requirements.txt); writes references.json. Run through regenerate.sh (it installs what this
needs). Existing entries are replaced only for the cases rendered in this run (--only).

Methods:
- "forward": forward.py, a light tracer on Mitsuba's ray_intersect and BSDF sampling
  (llvm_ad_mono), scoring both photodiodes in one pass; per-ray scores give the standard error.
- "path-spectral": Mitsuba's own `path` integrator (llvm_ad_spectral) with an `irradiancemeter`
  on each photodiode disk and a `specfilm` whose response is the diode's responsivity, the lamp a
  `blackbody` area emitter; the value is the mean over independent renders (different seeds), the
  standard error their spread.
"""

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)

C = "validation/mitsuba/cases/"


def coaxial_view_factor(r1, r2, h):
    a, b = r1 / h, r2 / h
    x = 1 + (1 + b * b) / (a * a)
    return 0.5 * (x - math.sqrt(x * x - 4 * (b / a) ** 2))


CASES = [
    dict(name="disk_to_disk", bench=C + "disk_to_disk.ron", pattern="all-plus", rays=1e7,
         what="closed form: Lambertian disk to coaxial disk, P = Phi F12",
         closed_form=[1.0 * coaxial_view_factor(5.0, 10.0, 10.0), 0.0]),
    dict(name="lens_focus", bench=C + "lens_focus.ron", pattern="all-plus", rays=3e7,
         what="a lens focusing a disk lamp onto a 3 mm diode (aberrated, partly filled)"),
    dict(name="chart_lens", bench=C + "chart_lens.ron", pattern="all-plus", rays=1.6e8,
         what="collimator, iris, image chart (T = 1 % chrome), imaging lens, diode"),
    dict(name="dmd_all_plus", bench="scenes/tests/symmetric_arms.ron", pattern="all-plus",
         rays=2e7, what="small DMD bench, every unit in state +"),
    dict(name="dmd_all_minus", bench="scenes/tests/symmetric_arms.ron", pattern="all-minus",
         rays=2e7, what="small DMD bench, every unit in state -"),
    dict(name="dmd_random", bench="scenes/tests/symmetric_arms.ron", pattern="random:1234",
         rays=2e7, what="small DMD bench, random pattern S"),
    dict(name="dmd_complement", bench="scenes/tests/symmetric_arms.ron",
         pattern="complement-random:1234", rays=2e7,
         what="small DMD bench, the complement of S"),
    dict(name="misaligned_all_plus", bench=C + "dmd_misaligned.ron", pattern="all-plus",
         rays=2e7, what="arm - misaligned (imbalance), every unit in state +"),
    dict(name="misaligned_all_minus", bench=C + "dmd_misaligned.ron", pattern="all-minus",
         rays=2e7, what="arm - misaligned (imbalance), every unit in state -"),
    dict(name="ghost_plate", bench=C + "ghost_plate.ron", pattern="all-plus", rays=1e7,
         what="tilted glass plate: the - diode sees only its surface reflections"),
    dict(name="paper_bench", bench=C + "paper_bench.ron", pattern="random:5", rays=2e9,
         what="the full paper bench (850 nm substitute), random pattern"),
    dict(name="paper_all_plus", bench=C + "paper_bench.ron", pattern="all-plus", rays=4e7,
         what="the full paper bench (850 nm substitute), every unit in state + (off-arm leak)"),
    dict(name="spectral_disk", bench=C + "spectral_disk.ron", pattern="all-plus",
         method="path-spectral", renders=8, spp=1 << 20,
         what="2800 K blackbody disk to a silicon diode (photocurrent, A)"),
]


def export(spibench, case, out, spectral=False):
    cmd = [spibench, "export-mitsuba", os.path.join(ROOT, case["bench"]), "--out", out,
           "--pattern", case["pattern"]]
    if spectral:
        cmd.append("--spectral")
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def render_forward(case, scene_dir, seed, recentre=True, offset_mm=(0.0, 0.0, 0.0)):
    import forward

    scene, manifest, shift = forward.load(scene_dir, "llvm_ad_mono", recentre=recentre,
                                          offset_mm=offset_mm)
    res, n = forward.trace(scene, manifest, int(case["rays"]), seed)
    return res, dict(variant="llvm_ad_mono",
                     method="forward light tracer (forward.py), re-centred" if recentre
                     else "forward light tracer (forward.py)",
                     samples=n, shift_mm=[round(x, 6) for x in shift])


# The harness check of position independence: a case moved by this much along each axis sign.
TRANSLATION_MM = 200.0
# |value(moved) - value(centred)| must stay below this many standard errors of the centred
# value. Both renders use the same seed, so the same rays: the difference measures the position
# dependence alone, not sampling noise (before re-centring, lens_focus moved by 200 mm read
# 0.1 %, about 2.3 standard errors of its 3e7-ray reference, lower).
TRANSLATION_TOLERANCE_SE = 1.5


def check_translation(spibench, names, scale, recentre=True):
    """Moves each named forward case by +-TRANSLATION_MM along z and along x (every exported
    shape and the lamp, as if the bench file placed the bench elsewhere), renders it as the
    references are rendered, and checks that the answer moves by less than
    TRANSLATION_TOLERANCE_SE standard errors. Returns True when every comparison passes.
    With recentre=False it shows the old behaviour (each case traced where it sits), which
    fails: lens_focus moved by 200 mm read 0.08-0.11 % lower (z = -1.8 to -2.5 at 3e7 rays)."""
    import forward

    ok = True
    for i, case in enumerate(CASES):
        if case["name"] not in names or case.get("method", "forward") != "forward":
            continue
        case = dict(case)
        case["rays"] = int(case["rays"] * scale)
        seed = 1000 + i
        with tempfile.TemporaryDirectory() as tmp:
            export(spibench, case, tmp)
            base, _ = render_forward(case, tmp, seed, recentre=recentre)
            for axis in (2, 0):
                for sign in (1.0, -1.0):
                    d = [0.0, 0.0, 0.0]
                    d[axis] = sign * TRANSLATION_MM
                    with tempfile.TemporaryDirectory() as moved:
                        forward.translate_scene(tmp, moved, d)
                        res, _ = render_forward(case, moved, seed, recentre=recentre)
                    for k, diode in enumerate(("plus", "minus")):
                        (v0, se0), (v1, _) = base[k], res[k]
                        if se0 == 0.0:
                            z = 0.0 if v1 == v0 else math.inf
                        else:
                            z = (v1 - v0) / se0
                        passed = abs(z) < TRANSLATION_TOLERANCE_SE
                        ok &= passed
                        print(json.dumps({"check": "translation", "case": case["name"],
                                          "diode": diode, "moved_mm": d, "base": v0,
                                          "moved": v1, "se": se0, "z": round(z, 3),
                                          "rel": (v1 - v0) / v0 if v0 else 0.0,
                                          "pass": passed}), flush=True)
    return ok


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spibench", required=True)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every ray count")
    ap.add_argument("--out", default=os.path.join(HERE, "references.json"))
    ap.add_argument("--check-translation", nargs="*", default=None, metavar="CASE",
                    help="instead of rendering references, check that moving these cases "
                         f"(default lens_focus, paper_bench) by +-{TRANSLATION_MM:g} mm leaves "
                         "Mitsuba's answer unchanged; exit status 1 if not")
    ap.add_argument("--no-recentre", action="store_true",
                    help="with --check-translation: trace where the bench file puts the case "
                         "(the old behaviour), to see the check fail")
    args = ap.parse_args()
    import drjit
    import mitsuba

    if args.check_translation is not None:
        names = args.check_translation or ["lens_focus", "paper_bench"]
        ok = check_translation(args.spibench, names, args.scale, recentre=not args.no_recentre)
        print("translation check:", "pass" if ok else "FAIL")
        sys.exit(0 if ok else 1)

    refs = {"cases": []}
    if os.path.exists(args.out):
        with open(args.out) as f:
            refs = json.load(f)
    by_name = {c["name"]: c for c in refs["cases"]}
    for i, case in enumerate(CASES):
        if args.only and case["name"] not in args.only:
            continue
        case = dict(case)
        if "rays" in case:
            case["rays"] = int(case["rays"] * args.scale)
        seed = 1000 + i
        method = case.get("method", "forward")
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.time()
            summary = export(args.spibench, case, tmp, spectral=(method == "path-spectral"))
            if method == "forward":
                res, info = render_forward(case, tmp, seed)
            else:
                res, info = render_spectral(case, tmp, seed)
            seconds = time.time() - t0
        entry = {
            "name": case["name"],
            "what": case["what"],
            "bench": case["bench"],
            "pattern": case["pattern"],
            "substitute_wavelength_nm": summary["wavelength_nm"],
            "substitutions": summary["substitutions"],
            "quantity": "photocurrent_a" if method == "path-spectral" else "power_w",
            "plus": {"value": res[0][0], "stderr": res[0][1]},
            "minus": {"value": res[1][0], "stderr": res[1][1]},
            "samples": info["samples"],
            "seed": seed,
            "method": info["method"],
            "mitsuba_version": mitsuba.__version__,
            "drjit_version": drjit.__version__,
            "variant": info["variant"],
            "render_seconds": round(seconds, 1),
        }
        if "shift_mm" in info:
            entry["recentre_shift_mm"] = info["shift_mm"]
        if "closed_form" in case:
            entry["closed_form"] = case["closed_form"]
        by_name[case["name"]] = entry
        print(json.dumps({k: entry[k] for k in ("name", "plus", "minus", "render_seconds")}),
              flush=True)
    order = [c["name"] for c in CASES]
    refs["cases"] = sorted(by_name.values(), key=lambda e: order.index(e["name"])
                           if e["name"] in order else len(order))
    refs["note"] = ("Mitsuba 3 references for spibench (validation/README.md). Generated by "
                    "validation/mitsuba/regenerate.sh; never written by cargo test.")
    tmp = args.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(refs, f, indent=1)
        f.write("\n")
    os.replace(tmp, args.out)


if __name__ == "__main__":
    main()
