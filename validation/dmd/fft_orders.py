"""Order efficiencies of a tilted-micromirror array by FFT of the reflected field.

An independent check of spibench's diffractive DMD model (src/optics/diffraction.rs,
docs/dmd_diffraction.md). For a plane wave of direction d and wavelength λ on a patch of N × N
mirrors (DLP7000: pitch 13.68 µm, fill factor 0.92, ±12° about the diagonal), the script

1. builds the reflected field in the array plane z = 0 on a grid of M × M samples per mirror
   (each sample the average of SS × SS sub-samples) by tracing back from each sample along the
   specular direction u_s to the mirror fronts of the 3 × 3 neighbouring cells (the mirrors
   placed by their rotation matrices), with the phase of the optical path k·(d·r + t) (r the
   point on the mirror, t the distance from r to the plane along u_s), divided by the incident
   wave's transverse phase k·d_xy·ρ so that it is periodic. Two fields: `efficiency` adds every
   mirror's field (no mirror hides another: the assumptions of spibench's model), and
   `efficiency_shadowed` keeps only the mirror seen from the far field along u_s and only where
   the illumination reaches it past the neighbours (the shadowing the model leaves out);
2. takes the 2-D FFT of the N × N patch: the patch is one period of the infinite array repeated
   N times, so order (m, n), direction cosines (d_x + mλ/p, d_y + nλ/p), falls exactly on bin
   (mN, nN);
3. divides out the sub-sample averaging's transfer function and normalises by the reflected
   field's mean |U|² (Parseval): P_mn = |c_mn|² / ⟨|U|²⟩, the share of order (m, n) of the power
   the mirrors reflect (evanescent orders included in the total).

It writes orders.csv: one row per (case, order) with P_mn > 1e-4 in either field. Needs numpy only:
    python3 validation/dmd/fft_orders.py
The Rust test (src/optics/diffraction/tests.rs, `fft_reference_agrees`) reads orders.csv.
"""

import csv
import math
import os

import numpy as np

PITCH = 13.68e-6
FILL = 0.92
TILT = math.radians(12.0)
HINGE = math.radians(45.0)
N = 2  # mirrors per side of the patch (one period of the array, repeated)
M = 128  # samples per pitch
SS = 4  # sub-samples per sample and axis


def rotation(axis, angle):
    """Rodrigues' rotation matrix about the unit `axis` by `angle` (right-handed)."""
    a = np.asarray(axis, float)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def mirror(state):
    h = (math.cos(HINGE), math.sin(HINGE), 0.0)
    return rotation(h, TILT if state == "plus" else -TILT)


def hit_mirror(px, py, pz, v, rot, side, forward):
    """First mirror front along p + t·v (t > 0 when forward, any t otherwise: smallest t) among
    the 3 × 3 cells around p's cell. Returns (t, hit mask)."""
    n = rot @ np.array([0.0, 0.0, 1.0])
    best = np.full(px.shape, np.inf)
    col = np.floor(px / PITCH)
    row = np.floor(py / PITCH)
    den = v @ n
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            cx = (col + di + 0.5) * PITCH
            cy = (row + dj + 0.5) * PITCH
            t = -((px - cx) * n[0] + (py - cy) * n[1] + pz * n[2]) / den
            rx, ry, rz = px + t * v[0] - cx, py + t * v[1] - cy, pz + t * v[2]
            lx = rot[0, 0] * rx + rot[1, 0] * ry + rot[2, 0] * rz
            ly = rot[0, 1] * rx + rot[1, 1] * ry + rot[2, 1] * rz
            inside = (np.abs(lx) <= side / 2) & (np.abs(ly) <= side / 2)
            if forward:
                inside &= t > 1e-12
            better = inside & (t < best)
            best = np.where(better, t, best)
    return best, np.isfinite(best)


def orders(wl, d, state):
    """Order shares by FFT, two ways: `sup`, every mirror's reflected field carried along u_s
    to the plane and added (the model's assumptions: no mirror hides another), and `vis`, only
    the field of the mirror seen from the far field along u_s and lit by the illumination (what
    the neighbours' shadowing leaves)."""
    rot = mirror(state)
    n = rot @ np.array([0.0, 0.0, 1.0])
    d = np.asarray(d, float) / np.linalg.norm(d)
    us = d - 2 * (d @ n) * n
    side = PITCH * math.sqrt(FILL)
    k = 2 * math.pi / wl
    delta = PITCH / M
    g = (np.arange(N * M) + 0.5) * delta
    fields = {"sup": np.zeros((N * M, N * M), complex), "vis": np.zeros((N * M, N * M), complex)}
    areas = {"sup": 0.0, "vis": 0.0}
    for a in range(SS):
        for b in range(SS):
            ox = ((a + 0.5) / SS - 0.5) * delta
            oy = ((b + 0.5) / SS - 0.5) * delta
            px, py = np.meshgrid(g + ox, g + oy, indexing="ij")
            pz = np.zeros_like(px)
            col, row = np.floor(px / PITCH), np.floor(py / PITCH)
            best = np.full(px.shape, np.inf)
            best_phase = np.zeros(px.shape)
            best_r = [np.zeros(px.shape) for _ in range(3)]
            for di in (-1, 0, 1):
                for dj in (-1, 0, 1):
                    cx = (col + di + 0.5) * PITCH
                    cy = (row + dj + 0.5) * PITCH
                    # p = r + t·u_s with r on this mirror's plane.
                    t = ((px - cx) * n[0] + (py - cy) * n[1] + pz * n[2]) / (us @ n)
                    rx, ry, rz = px - t * us[0], py - t * us[1], pz - t * us[2]
                    lx = rot[0, 0] * (rx - cx) + rot[1, 0] * (ry - cy) + rot[2, 0] * rz
                    ly = rot[0, 1] * (rx - cx) + rot[1, 1] * (ry - cy) + rot[2, 1] * rz
                    inside = (np.abs(lx) <= side / 2) & (np.abs(ly) <= side / 2)
                    # The optical path: the incident phase at r, then t along u_s; divided by
                    # the incident wave's transverse phase at p.
                    phase = k * (d[0] * rx + d[1] * ry + d[2] * rz + t) - k * (d[0] * px + d[1] * py)
                    fields["sup"] += np.where(inside, np.exp(1j * phase), 0.0)
                    areas["sup"] += inside.mean()
                    # Seen from the far field: the mirror met first coming down along −u_s,
                    # i.e. the largest t.
                    better = inside & ((best == np.inf) | (t > best))
                    best = np.where(better, t, best)
                    best_phase = np.where(better, phase, best_phase)
                    for c, v in zip(best_r, (rx, ry, rz)):
                        c[...] = np.where(better, v, c)
            hit = np.isfinite(best)
            # Lit? Back along −d from the point: no other mirror in the way.
            rx, ry, rz = best_r
            _, shadowed = hit_mirror(rx - 1e-9 * d[0], ry - 1e-9 * d[1], rz - 1e-9 * d[2],
                                     -d, rot, side, forward=True)
            lit = hit & ~shadowed
            fields["vis"] += np.where(lit, np.exp(1j * best_phase), 0.0)
            areas["vis"] += lit.mean()
    lim = M // 2 - 1
    ms = np.arange(-lim, lim + 1)
    # Transfer function of the SS-point average at order m (frequency m/p).
    offsets = ((np.arange(SS) + 0.5) / SS - 0.5) * delta
    h = np.abs(np.exp(2j * math.pi * np.outer(ms / PITCH, offsets)).mean(axis=1))
    shares = {}
    for key in fields:
        area = areas[key] / (SS * SS)
        spec = np.fft.fft2(fields[key] / (SS * SS)) / (N * M) ** 2
        c = spec[np.ix_((ms * N) % (N * M), (ms * N) % (N * M))]
        shares[key] = (np.abs(c) ** 2 / np.outer(h * h, h * h) / area, area)
    p_sup, area_sup = shares["sup"]
    p_vis, area_vis = shares["vis"]
    out = [(int(ms[i]), int(ms[j]), float(p_sup[i, j]), float(p_vis[i, j]))
           for i, j in zip(*np.nonzero((p_sup > 1e-4) | (p_vis > 1e-4)))]
    return out, area_sup, area_vis


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    s24 = math.sin(math.radians(24.0)) / math.sqrt(2.0)
    c24 = math.cos(math.radians(24.0))
    incidences = {
        # Along −z (the paper bench's illumination).
        "normal": (0.0, 0.0, -1.0),
        # 24° in the diagonal plane: state + sends it along the array normal (TI's layout).
        "ti24": (-s24, s24, -c24),
    }
    rows = []
    for name, d in incidences.items():
        for wl_nm in (450.0, 650.0, 900.0):
            for state in ("plus", "minus"):
                found, area_sup, area_vis = orders(wl_nm * 1e-9, d, state)
                total = sum(p for _, _, p, _ in found)
                print(f"{name} {wl_nm:.0f} nm {state}: footprint {area_sup:.5f} "
                      f"(seen and lit {area_vis:.5f}), {len(found)} orders > 1e-4 carry "
                      f"{total:.5f}")
                for m, nn, p, pv in found:
                    rows.append((name, wl_nm, d[0], d[1], d[2], state, m, nn, p, pv))
    with open(os.path.join(here, "orders.csv"), "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["incidence", "wavelength_nm", "dx", "dy", "dz", "state", "m", "n",
                    "efficiency", "efficiency_shadowed"])
        for r in rows:
            w.writerow([r[0], f"{r[1]:.1f}", f"{r[2]:.12f}", f"{r[3]:.12f}", f"{r[4]:.12f}",
                        r[5], r[6], r[7], f"{r[8]:.9e}", f"{r[9]:.9e}"])


if __name__ == "__main__":
    main()
