"""The diffractive model's efficiency into an f/2.4 collection cone for TI's layout.

TI quotes about 86 % diffraction efficiency into an f/2.4 collection cone in the visible
(docs/bench-facts.md §2.2). This evaluates spibench's envelope (the formula of
src/optics/diffraction.rs, docs/dmd_diffraction.md) for the DLP7000 in TI's layout: light at 24°
in the diagonal plane, state + sending it along the array normal, collected within an f/2.4 cone
(half-angle 12.0°) around the normal; once for a single plane wave and once with the
illumination filling an f/2.4 cone (150 random directions per wavelength, seed 1).
    python3 validation/dmd/ti_efficiency.py
"""

import math

import numpy as np

PITCH = 13.68e-6
FILL = 0.92
TILT = math.radians(12.0)


def rotation(axis, angle):
    a = np.asarray(axis, float)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def orders(wl, d, radius=60):
    """Direction cosines (α, β) and shares P of the orders within ±radius of the peak."""
    h = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0)
    rot = rotation(h, TILT)
    n, e1, e2 = rot @ [0, 0, 1.0], rot @ [1.0, 0, 0], rot @ [0, 1.0, 0]
    d = np.asarray(d, float) / np.linalg.norm(d)
    us = d - 2 * (d @ n) * n
    side = PITCH * math.sqrt(FILL)
    shear = lambda e: side * np.array([e[0] - e[2] * us[0] / us[2], e[1] - e[2] * us[1] / us[2]])
    E1, E2 = shear(e1), shear(e2)
    det = abs(E1[0] * E2[1] - E1[1] * E2[0])
    q, k = wl / PITCH, 2 * math.pi / wl
    m0, n0 = np.round((us[0] - d[0]) / q), np.round((us[1] - d[1]) / q)
    mm, nn = np.meshgrid(np.arange(-radius, radius + 1) + m0, np.arange(-radius, radius + 1) + n0,
                         indexing="ij")
    a, b = d[0] + mm * q, d[1] + nn * q
    kx, ky = k * (a - us[0]), k * (b - us[1])
    s2 = lambda x: np.sinc(x / math.pi) ** 2
    return a, b, det / PITCH**2 * s2((kx * E1[0] + ky * E1[1]) / 2) * s2((kx * E2[0] + ky * E2[1]) / 2)


def main():
    s24 = math.sin(math.radians(24.0)) / math.sqrt(2.0)
    d0 = np.array([-s24, s24, -math.cos(math.radians(24.0))])
    sc = 1 / (2 * 2.4)
    wls = np.arange(420e-9, 681e-9, 20e-9)
    single = []
    for wl in wls:
        a, b, p = orders(wl, d0)
        single.append(p[a * a + b * b <= sc * sc].sum())
    rng = np.random.default_rng(1)
    u1 = np.cross(d0, [0, 0, 1.0])
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(d0, u1)
    cone = []
    for wl in wls:
        acc = 0.0
        for _ in range(150):
            r, ph = sc * math.sqrt(rng.random()), 2 * math.pi * rng.random()
            d = d0 + r * math.cos(ph) * u1 + r * math.sin(ph) * u2
            a, b, p = orders(wl, d / np.linalg.norm(d))
            acc += p[a * a + b * b <= sc * sc].sum()
        cone.append(acc / 150)
    print(f"plane wave: mean {np.mean(single):.4f} ({min(single):.4f}-{max(single):.4f})")
    print(f"f/2.4 illumination: mean {np.mean(cone):.4f} ({min(cone):.4f}-{max(cone):.4f})")


if __name__ == "__main__":
    main()
