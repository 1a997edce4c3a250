"""A forward light tracer on Mitsuba 3's own primitives: the independent reference for spibench.

Rays leave the exported lamp (uniform over the filament, cosine-weighted inside the emission
cone that the lamp housing passes: each ray carries Phi * sin^2(theta_max) / N), then follow
Mitsuba's own intersections (`scene.ray_intersect`, the exported meshes) and Mitsuba's own BSDF
sampling in importance (light-transport) mode: `dielectric` chooses reflection or refraction by
Fresnel, `conductor` multiplies by its reflectance, `mask` passes or blocks, black `diffuse`
ends the path. A path that meets a photodiode disk from its front scores its power there; from
behind it is absorbed (the diode's housing). Both photodiodes are scored in one pass. The lamp
shape (black, for Mitsuba's own integrators) is transparent here, as spibench's filament is.

Why not Mitsuba's integrators: `path` with an `irradiancemeter` works but only ~1e-4 of the
detector's directions find a small filament through the bench (hours for 0.1 %), and `ptracer`
with an `irradiancemeter` is wrong (docs/mitsuba.md). The `path` integrator is still used for
the closed-form and spectral cases (run_references.py), where it is efficient.

Position independence: Mitsuba pushes the start of every new segment off the surface by about
(1 + max|p|) x 8.9e-5 in scene units (its RayEpsilon scaled by the largest coordinate), so in
millimetres 18 um at 200 mm from the origin and 90 um at 1 m. That offset is a physical error for
a lens (a ray refracted at the front surface starts 18 um along the normal, not on the surface):
lens_focus, with its lens at z = 200 mm, read 0.1 % lower than the same case at the origin, and a
lens at 1 m 3.5 % lower. `load` therefore re-centres every case before tracing: it appends a
translation to every shape's to_world that puts the centre of the scene's bounding box at the
origin (and moves the lamp frame of the manifest with it), so the offset is that of a bench of
the case's own size, whatever coordinates the bench file uses. The translation is exact for the
analytic shapes (disks) and rounds each mesh vertex once, to float32 (about 1e-5 mm at 200 mm),
far below any tolerance. `check_translation` (run_references.py --check-translation) verifies
that a case moved by +-200 mm gives the same answer.

Standard errors: the per-ray scores are independent, so se = std(score) / sqrt(N) (accumulated
in float64 over passes of `--rays-per-pass` rays).
"""

import json
import math
import os
import sys
import tempfile
import xml.etree.ElementTree as ET

import numpy as np


def translate_scene(scene_dir, out_dir, shift_mm):
    """Copies the exported case in `scene_dir` to `out_dir` with every shape translated by
    `shift_mm` (a translation appended to each shape's to_world, so applied after the shape's own
    transform) and the manifest's lamp origin moved with it. Mesh files are linked, not copied."""
    tree = ET.parse(os.path.join(scene_dir, "scene.xml"))
    value = " ".join(f"{float(c):.9e}" for c in shift_mm)
    for shape in tree.getroot().iter("shape"):
        tf = shape.find("transform[@name='to_world']")
        if tf is None:
            tf = ET.Element("transform", {"name": "to_world"})
            shape.insert(0, tf)
        ET.SubElement(tf, "translate", {"value": value})
    tree.write(os.path.join(out_dir, "scene.xml"))
    with open(os.path.join(scene_dir, "manifest.json")) as f:
        manifest = json.load(f)
    manifest["lamp"]["origin_mm"] = [o + d for o, d in zip(manifest["lamp"]["origin_mm"], shift_mm)]
    with open(os.path.join(out_dir, "manifest.json"), "w") as f:
        json.dump(manifest, f)
    for name in os.listdir(scene_dir):
        if name not in ("scene.xml", "manifest.json"):
            os.symlink(os.path.join(os.path.abspath(scene_dir), name), os.path.join(out_dir, name))


def _load_file(scene_dir):
    import mitsuba as mi

    with open(os.path.join(scene_dir, "manifest.json")) as f:
        manifest = json.load(f)
    cwd = os.getcwd()
    os.chdir(scene_dir)
    try:
        scene = mi.load_file("scene.xml")
    finally:
        os.chdir(cwd)
    return scene, manifest


def load(scene_dir, variant="llvm_ad_mono", recentre=True, offset_mm=(0.0, 0.0, 0.0)):
    """Loads an exported case. With `recentre`, the scene is translated so that the centre of
    its bounding box sits at `offset_mm` (the origin by default; the module documentation says
    why). Returns (scene, manifest, shift_mm)."""
    import mitsuba as mi

    mi.set_variant(variant)
    scene, manifest = _load_file(scene_dir)
    if not recentre:
        return scene, manifest, [0.0, 0.0, 0.0]
    bbox = scene.bbox()
    centre = [0.5 * (float(bbox.min[i]) + float(bbox.max[i])) for i in range(3)]
    shift = [offset_mm[i] - centre[i] for i in range(3)]
    with tempfile.TemporaryDirectory() as tmp:
        translate_scene(scene_dir, tmp, shift)
        scene, manifest = _load_file(tmp)
    return scene, manifest, shift


def pass_seed(seed, pass_index):
    """The 32-bit sampler seed of one pass: SplitMix64 of (seed, pass) (Mitsuba's sampler seed is
    32-bit, so the old `seed * 1_000_003 + pass` overflowed for seeds >= 4295)."""
    z = ((seed << 32) + pass_index + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return (z ^ (z >> 31)) & 0xFFFFFFFF


def trace(scene, manifest, rays, seed, rays_per_pass=1 << 20, max_depth=None):
    """Returns per-detector (mean, stderr) of the detected power (W) and the rays traced."""
    import drjit as dr
    import mitsuba as mi

    lamp = manifest["lamp"]
    o = np.array(lamp["origin_mm"])
    u, v, w = (np.array(lamp[k]) for k in ("u", "v", "w"))
    shape = lamp["shape"]
    power = lamp["power_w"]
    sin2 = lamp["sin2_max"]
    depth_cap = max_depth or manifest["max_depth"]
    # The detector shapes, by id.
    dets = {}
    for s in scene.shapes():
        if s.id() in ("pd_plus", "pd_minus"):
            dets[s.id()] = s
    order = ["pd_plus", "pd_minus"]
    lamp_ptr = mi.ShapePtr([s for s in scene.shapes() if s.id() == "lamp"][0])
    sums = np.zeros(2)
    sums2 = np.zeros(2)
    done = 0
    pass_index = 0
    while done < rays:
        n = int(min(rays_per_pass, rays - done))
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(pass_seed(seed, pass_index), n)
        # Position on the filament.
        p2 = sampler.next_2d()
        if shape["type"] == "rect":
            x = (2 * p2.x - 1) * shape["half_u_mm"]
            y = (2 * p2.y - 1) * shape["half_v_mm"]
        else:
            r = shape["radius_mm"] * dr.sqrt(p2.x)
            a = 2 * math.pi * p2.y
            x, y = r * dr.cos(a), r * dr.sin(a)
        # Cosine-weighted direction inside the cone sin^2(theta) <= sin2.
        d2 = sampler.next_2d()
        s2 = d2.x * sin2
        ct = dr.sqrt(dr.maximum(1 - s2, 0))
        st = dr.sqrt(s2)
        phi = 2 * math.pi * d2.y
        dl = [st * dr.cos(phi), st * dr.sin(phi), ct]
        org = mi.Point3f(*(o[i] + x * u[i] + y * v[i] for i in range(3)))
        dirn = mi.Vector3f(*(dl[0] * u[i] + dl[1] * v[i] + dl[2] * w[i] for i in range(3)))
        ray = mi.Ray3f(org, dr.normalize(dirn))
        weight = mi.Float(power * sin2)
        active = mi.Bool(True)
        score = [mi.Float(0.0), mi.Float(0.0)]
        ctx = mi.BSDFContext(mi.TransportMode.Importance)
        for _ in range(depth_cap):
            si = scene.ray_intersect(ray, active)
            active &= si.is_valid()
            # The filament is transparent to light (as in spibench): pass through the lamp
            # shape unchanged. This also absorbs any self-intersection of a ray just emitted
            # (float32 cannot offset a start point by 1e-6 mm at 600 mm from the origin).
            on_lamp = active & (si.shape == lamp_ptr)
            for k, name in enumerate(order):
                if name not in dets:
                    continue
                hit = active & (si.shape == mi.ShapePtr(dets[name]))
                front = hit & (dr.dot(ray.d, si.n) < 0)
                score[k] = dr.select(front, score[k] + weight, score[k])
                active &= ~hit
            scatter = active & ~on_lamp
            bsdf = si.bsdf(ray)
            bs, bw = bsdf.sample(ctx, si, sampler.next_1d(scatter), sampler.next_2d(scatter),
                                 scatter)
            bw = bw[0]  # llvm_ad_mono: a one-channel spectrum
            weight = dr.select(scatter, weight * bw, weight)
            active &= (weight > 0) & (on_lamp | dr.all(dr.isfinite(bs.wo)))
            wo = dr.select(on_lamp, ray.d, si.to_world(bs.wo))
            ray = si.spawn_ray(wo)
            sampler.schedule_state()
            dr.eval(ray, weight, active, score)
            if not dr.any(active):
                break
        for k in range(2):
            a = np.array(score[k], dtype=np.float64)
            sums[k] += a.sum()
            sums2[k] += (a * a).sum()
        done += n
        pass_index += 1
    mean = sums / done
    var = np.maximum(sums2 / done - mean * mean, 0.0)
    se = np.sqrt(var / done)
    return [(float(mean[k]), float(se[k])) for k in range(2)], done


if __name__ == "__main__":
    scene_dir, rays, seed = sys.argv[1], int(float(sys.argv[2])), int(sys.argv[3])
    scene, manifest, _ = load(scene_dir)
    res, n = trace(scene, manifest, rays, seed)
    print(json.dumps({"rays": n, "plus": res[0], "minus": res[1]}))
