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
    dict(name="chart_lens", bench=C + "chart_lens.ron", pattern="all-plus", rays=2e7,
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
    dict(name="paper_bench", bench="scenes/paper_bench.ron", pattern="random:5", rays=1e8,
         what="the full paper bench (850 nm substitute), random pattern"),
    dict(name="paper_all_plus", bench="scenes/paper_bench.ron", pattern="all-plus", rays=4e7,
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


def render_forward(case, scene_dir, seed):
    import forward

    scene, manifest = forward.load(scene_dir, "llvm_ad_mono")
    res, n = forward.trace(scene, manifest, int(case["rays"]), seed)
    return res, dict(variant="llvm_ad_mono", method="forward light tracer (forward.py)",
                     samples=n)


def render_spectral(case, scene_dir, seed):
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    mi.set_variant("llvm_ad_spectral")
    with open(os.path.join(scene_dir, "manifest.json")) as f:
        m = json.load(f)
    lamp = m["lamp"]
    sp = lamp["spectrum"]
    b0, b1 = m["band_nm"]

    def to_world(o, u, v, w, s):
        return mi.ScalarTransform4f(
            [[u[0] * s, v[0] * s, w[0], o[0]], [u[1] * s, v[1] * s, w[1], o[1]],
             [u[2] * s, v[2] * s, w[2], o[2]], [0, 0, 0, 1]])

    # Scene units: metres here, so that the blackbody's W m^-2 sr^-1 nm^-1 needs no scaling.
    mm = 1e-3
    o = [x * mm for x in lamp["origin_mm"]]
    emitter = {
        "type": "disk",
        "to_world": to_world(o, lamp["u"], lamp["v"], lamp["w"],
                             lamp["shape"]["radius_mm"] * mm),
        "bsdf": {"type": "diffuse", "reflectance": 0.0},
        "emitter": {"type": "area", "radiance": {
            "type": "blackbody", "temperature": sp["temperature_k"],
            "wavelength_min": b0, "wavelength_max": b1}},
    }
    results = []
    for d in m["detectors"]:
        table = d["responsivity_table_nm_a_per_w"]
        c = [x * mm for x in d["center_mm"]]
        n = d["normal"]
        nv = np.array(n, dtype=float)
        helper = np.array([1.0, 0, 0]) if abs(nv[0]) < 0.9 else np.array([0, 1.0, 0])
        su = helper - helper.dot(nv) * nv
        su /= np.linalg.norm(su)
        sv = np.cross(nv, su)
        srf = {"type": "irregular",
               "wavelengths": ", ".join(f"{t[0]:.6f}" for t in table),
               "values": ", ".join(f"{t[1]:.6f}" for t in table)}
        vals = []
        for k in range(case["renders"]):
            scene = mi.load_dict({
                "type": "scene",
                "integrator": {"type": "path", "max_depth": 8, "rr_depth": 8},
                "lamp": emitter,
                "det": {
                    "type": "disk",
                    "to_world": to_world(c, list(su), list(sv), list(nv), d["radius_mm"] * mm),
                    "bsdf": {"type": "diffuse", "reflectance": 0.0},
                    "sensor": {
                        "type": "irradiancemeter",
                        "sampler": {"type": "independent", "sample_count": case["spp"],
                                    "seed": seed * 1000 + k},
                        "film": {"type": "specfilm", "width": 1, "height": 1,
                                 "rfilter": {"type": "box"}, "srf": srf},
                    },
                },
            })
            img = np.array(mi.render(scene), dtype=np.float64).ravel()
            area_m2 = math.pi * (d["radius_mm"] * mm) ** 2
            vals.append(float(img[0]) * area_m2 * sp["emissivity"])
        vals = np.array(vals)
        results.append((float(vals.mean()), float(vals.std(ddof=1) / math.sqrt(len(vals)))))
    return results, dict(variant="llvm_ad_spectral",
                         method="path integrator + irradiancemeter + specfilm (SRF = responsivity)",
                         samples=case["renders"] * case["spp"])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spibench", required=True)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--scale", type=float, default=1.0, help="multiply every ray count")
    ap.add_argument("--out", default=os.path.join(HERE, "references.json"))
    args = ap.parse_args()
    import drjit
    import mitsuba

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
