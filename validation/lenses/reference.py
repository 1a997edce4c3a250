#!/usr/bin/env python3
"""Reference numbers for spibench's lens prescriptions, from rayoptics and from optiland.

For every shipped part (scenes/parts/*.zmx) and every valid test prescription
(validation/lenses/test_prescriptions/*.zmx) and each wavelength of WAVELENGTHS_NM this writes
to validation/lenses/reference.json:

- the paraxial EFL, BFL and FFL (mm), from each library;
- a meridional fan of real rays parallel to the axis at FAN_FRACTIONS of the first surface's
  semi-diameter, traced to the file's last surface (the image plane at the DISZ that follows the
  last glass surface): the y intercept there (mm) and the direction cosines (L, M, N) after the
  last refraction, from each library.

Both libraries are given the same surfaces and the same refractive indices: the script parses the
.zmx itself (a small parser below, the same for both, so that the encodings and UNIT IN are
handled once and identically) and builds each library's system through its API, with every glass
a Sellmeier model made from the coefficients of GLASSES (docs/glasses.md), never a library's own
catalogue. A third, hand-written paraxial trace (numpy) checks the two libraries' first-order
numbers and sign conventions.

Usage (see README.md for the environment):
    python validation/lenses/reference.py            # writes reference.json, prints agreement
    python validation/lenses/reference.py --check    # recomputes and compares with the file
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
OUT = HERE / "reference.json"

# He d line (587.5618 nm, written "587.6 nm" in catalogues) and the bench's 850 nm.
WAVELENGTHS_NM = [587.5618, 850.0]
FAN_FRACTIONS = [0.1, 0.3, 0.5, 0.7, 0.9]
MM_PER_INCH = 25.4
# One more ray per fan, at this fraction of the semi-diameter: its focus is the paraxial one to
# about (1e-5)^2 relative, a check of the paraxial numbers by the real trace.
SMALL_RAY_FRACTION = 1e-5
R2_NOTE = (
    "PARM 1 (the r^2 term) is non-zero: rayoptics' and optiland's paraxial efl/bfl/ffl use the "
    "base curvature CURV alone, while their real rays (small_ray) and numpy_paraxial include the "
    "r^2 term (paraxial curvature CURV + 2*PARM1). The physical paraxial values are "
    "numpy_paraxial's."
)

# Three-term Sellmeier: n^2 - 1 = sum B_i l^2 / (l^2 - C_i), l in um, C in um^2.
# (B1, B2, B3), (C1, C2, C3), range (um). Sources in docs/glasses.md.
GLASSES = {
    "N-BK7": ((1.03961212, 0.231792344, 1.01046945),
              (0.00600069867, 0.0200179144, 103.560653), (0.3, 2.5)),
    "N-BAK1": ((1.12365662, 0.309276848, 0.881511957),
               (0.00644742752, 0.0222284402, 107.297751), (0.32, 2.5)),
    "N-SF5": ((1.52481889, 0.187085527, 1.42729015),
              (0.011254756, 0.0588995392, 129.141675), (0.37, 2.5)),
    "N-LAK22": ((1.14229781, 0.535138441, 1.04088385),
                (0.00585778594, 0.0198546147, 100.834017), (0.31, 2.5)),
    "N-SF6HT": ((1.77931763, 0.338149866, 2.08734474),
                (0.0133714182, 0.0617533621, 174.01759), (0.37, 2.5)),
    "S-LAH64": ((1.83021453, 0.29156359, 1.28544024),
                (0.0090482329, 0.0330756689, 89.3675501), (0.32, 2.4)),
}


def sellmeier_index(glass: str, wavelength_um: float) -> float:
    b, c, (lo, hi) = GLASSES[glass]
    if not lo <= wavelength_um <= hi:
        raise ValueError(f"{glass}: {wavelength_um} um outside {lo}-{hi} um")
    l2 = wavelength_um * wavelength_um
    return math.sqrt(1.0 + sum(bi * l2 / (l2 - ci) for bi, ci in zip(b, c)))


# ---------------------------------------------------------------------------------------------
# A small .zmx reader: the operands the lens element needs, nothing else.
# ---------------------------------------------------------------------------------------------


def decode_zmx(data: bytes) -> str:
    """UTF-16 (BOM either order, or LE/BE recognised by its NUL bytes), UTF-8, else ISO-8859-1."""
    if data.startswith(b"\xff\xfe"):
        return data[2:].decode("utf-16-le")
    if data.startswith(b"\xfe\xff"):
        return data[2:].decode("utf-16-be")
    if data.startswith(b"\xef\xbb\xbf"):
        return data[3:].decode("utf-8")
    head = data[:200]
    if len(head) >= 4 and head[1::2].count(0) > len(head) // 4 and head[0::2].count(0) == 0:
        return data.decode("utf-16-le")
    if len(head) >= 4 and head[0::2].count(0) > len(head) // 4 and head[1::2].count(0) == 0:
        return data.decode("utf-16-be")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("iso-8859-1")


@dataclass
class Surf:
    number: int
    kind: str = "STANDARD"
    curv: float = 0.0  # 1/mm after unit conversion
    conic: float = 0.0
    parm: list = field(default_factory=lambda: [0.0] * 8)  # r^2 ... r^16 coefficients
    disz: float | None = None  # mm
    glass: str | None = None
    semi_diam: float = 0.0  # mm
    stop: bool = False


def parse_zmx(path: Path) -> list[Surf]:
    text = decode_zmx(path.read_bytes())
    unit = "MM"
    surfs: list[Surf] = []
    for raw in text.splitlines():
        tok = raw.split()
        if not tok:
            continue
        op = tok[0]
        if op == "MODE" and tok[1] != "SEQ":
            raise ValueError(f"{path}: MODE {tok[1]}")
        elif op == "UNIT":
            unit = tok[1]
        elif op == "SURF":
            surfs.append(Surf(int(tok[1])))
        elif not surfs:
            continue
        elif op == "TYPE":
            if tok[1] not in ("STANDARD", "EVENASPH"):
                raise ValueError(f"{path}: TYPE {tok[1]}")
            surfs[-1].kind = tok[1]
        elif op == "CURV":
            surfs[-1].curv = float(tok[1])
        elif op == "CONI":
            surfs[-1].conic = float(tok[1])
        elif op == "PARM":
            i = int(tok[1])
            if not 1 <= i <= 8:
                raise ValueError(f"{path}: PARM {i}")
            surfs[-1].parm[i - 1] = float(tok[2])
        elif op == "DISZ":
            surfs[-1].disz = math.inf if tok[1] == "INFINITY" else float(tok[1])
        elif op == "GLAS":
            surfs[-1].glass = tok[1]
        elif op == "DIAM":
            surfs[-1].semi_diam = float(tok[1])
        elif op == "STOP":
            surfs[-1].stop = True
    scale = {"MM": 1.0, "IN": MM_PER_INCH}[unit]
    for s in surfs:
        # CURV is 1/length; PARM i multiplies r^(2i), so its unit is length^(1 - 2i).
        s.curv /= scale
        s.parm = [p * scale ** (1 - 2 * (i + 1)) for i, p in enumerate(s.parm)]
        if s.disz is not None and math.isfinite(s.disz):
            s.disz *= scale
        s.semi_diam *= scale
        if s.kind == "STANDARD" and any(s.parm):
            raise ValueError(f"{path}: PARM on a STANDARD surface")
    return surfs


def lens_surfaces(surfs: list[Surf]) -> tuple[list[Surf], float]:
    """The element: first surface with a glass after it to the last glass surface inclusive,
    plus the distance from that last surface to the file's last (image) surface."""
    glass_idx = [i for i, s in enumerate(surfs) if s.glass is not None]
    first, last_glass = glass_idx[0], glass_idx[-1]
    element = surfs[first:last_glass + 2]  # up to the surface where the last glass ends
    image_distance = sum(s.disz for s in surfs[last_glass + 1:-1])
    # The element's last surface is the exit face; its DISZ counts toward the image distance.
    return element, image_distance


# ---------------------------------------------------------------------------------------------
# Independent paraxial trace (numpy), to check both libraries' conventions.
# ---------------------------------------------------------------------------------------------


def paraxial(element: list[Surf], wavelength_um: float) -> dict:
    """y-nu trace; the paraxial curvature of an even asphere is CURV + 2*PARM1."""
    def media():
        ns = [1.0]
        for s in element:
            ns.append(sellmeier_index(s.glass, wavelength_um) if s.glass else 1.0)
        return ns

    ns = media()

    def trace(surfaces, indices):
        y, u = 1.0, 0.0
        for k, s in enumerate(surfaces):
            c = s.curv + 2.0 * s.parm[0]
            n0, n1 = indices[k], indices[k + 1]
            u = (n0 * u - y * c * (n1 - n0)) / n1
            if k + 1 < len(surfaces):
                y = y + u * surfaces[k].disz
        return y, u

    y, u = trace(element, ns)
    power = -u  # y0 = 1, image space in air
    if abs(power) < 1e-15:
        return {"efl_mm": None, "bfl_mm": None, "ffl_mm": None}
    efl = 1.0 / power
    bfl = -y / u
    # Front: the reversed system, each surface's curvature negated.
    rev = []
    for k in range(len(element) - 1, -1, -1):
        s = element[k]
        r = Surf(s.number, s.kind, -s.curv, s.conic, [-p for p in s.parm])
        r.disz = element[k - 1].disz if k > 0 else None
        rev.append(r)
    y, u = trace(rev, ns[::-1])
    ffl = -y / u
    return {"efl_mm": efl, "bfl_mm": bfl, "ffl_mm": ffl}


# ---------------------------------------------------------------------------------------------
# rayoptics
# ---------------------------------------------------------------------------------------------


class RoSellmeier:
    """The glass interface rayoptics asks of a medium: name(), catalog_name(), rindex(nm)."""

    def __init__(self, glass: str):
        self.glass = glass

    def name(self):
        return self.glass

    def catalog_name(self):
        return "spibench"

    def rindex(self, wv_nm):
        return sellmeier_index(self.glass, float(wv_nm) / 1000.0)


def rayoptics_numbers(element, image_distance, wavelength_nm, heights):
    from rayoptics.elem.profiles import EvenPolynomial
    from rayoptics.environment import FieldSpec, OpticalModel, PupilSpec, WvlSpec
    from rayoptics.raytr import raytrace as rt

    opm = OpticalModel()
    sm, osp = opm["seq_model"], opm["optical_spec"]
    osp["pupil"] = PupilSpec(osp, key=["object", "epd"], value=2.0 * element[0].semi_diam)
    osp["fov"] = FieldSpec(osp, key=["object", "angle"], flds=[0.0])
    osp["wvls"] = WvlSpec([(wavelength_nm, 1.0)], ref_wl=0)
    opm.radius_mode = True
    sm.gaps[0].thi = 1.0e10
    for k, s in enumerate(element):
        thi = s.disz if k + 1 < len(element) else image_distance
        medium = RoSellmeier(s.glass) if s.glass else "air"
        radius = 1.0 / s.curv if s.curv != 0.0 else 0.0
        sm.add_surface([radius, thi, medium] if s.glass else [radius, thi])
        if k == 0:
            sm.set_stop()
        if s.kind == "EVENASPH" or s.conic != 0.0:
            sm.ifcs[sm.cur_surface].profile = EvenPolynomial(
                c=s.curv, cc=s.conic, coefs=list(s.parm))
        sm.ifcs[sm.cur_surface].set_max_aperture(s.semi_diam)
    opm.update_model()
    fod = opm["analysis_results"]["parax_data"].fod
    if abs(fod.power) < 1e-15:
        first = {"efl_mm": None, "bfl_mm": None, "ffl_mm": None}
    else:
        # rayoptics: bfl from the last interface to the rear focus (+ after it); ffl from the
        # first interface to the front focus (- before it). Ours: both + outside the lens.
        first = {"efl_mm": fod.efl, "bfl_mm": fod.bfl, "ffl_mm": -fod.ffl}
    # Real rays: the object gap is set to 5 mm for the trace so that no 1e10 mm path enters
    # the arithmetic; each ray starts at (0, h, 0) on the object plane, along +z.
    sm.gaps[0].thi = 5.0
    rays = []
    for h in heights:
        try:
            ray, _, _ = rt.trace(sm, np.array([0.0, h, 0.0]), np.array([0.0, 0.0, 1.0]),
                                 wavelength_nm, check_apertures=False)
            pt, d = ray[-1][0], ray[-1][1]
            rays.append({"height_mm": h, "y_mm": float(pt[1]),
                         "direction": [float(d[0]), float(d[1]), float(d[2])]})
        except Exception as e:  # a miss or TIR: recorded, not hidden
            rays.append({"height_mm": h, "y_mm": None, "direction": None, "error": repr(e)})
    return {**first, "rays": rays}


# ---------------------------------------------------------------------------------------------
# optiland
# ---------------------------------------------------------------------------------------------


def optiland_numbers(element, image_distance, wavelength_nm, heights):
    import optiland.backend as be
    from optiland import optic
    from optiland.materials.base import BaseMaterial
    from optiland.rays import RealRays

    class OlSellmeier(BaseMaterial):
        def __init__(self, glass):
            super().__init__()
            self.glass = glass

        def _calculate_n(self, wavelength, **kwargs):
            w = np.atleast_1d(np.asarray(be.to_numpy(wavelength), dtype=float))
            n = np.array([sellmeier_index(self.glass, float(x)) for x in w])
            return be.array(n if np.ndim(wavelength) else n[0])

        def _calculate_k(self, wavelength, **kwargs):
            return be.array(np.zeros(np.shape(be.to_numpy(wavelength))) if np.ndim(wavelength)
                            else 0.0)

    lens = optic.Optic()
    lens.add_surface(index=0, thickness=np.inf)
    for k, s in enumerate(element):
        thi = s.disz if k + 1 < len(element) else image_distance
        kwargs = dict(index=k + 1, thickness=thi,
                      radius=1.0 / s.curv if s.curv != 0.0 else np.inf,
                      is_stop=(k == 0), conic=s.conic)
        if s.glass:
            kwargs["material"] = OlSellmeier(s.glass)
        if s.kind == "EVENASPH":
            kwargs.update(surface_type="even_asphere", coefficients=list(s.parm),
                          tol=1e-14, max_iter=100)
        lens.add_surface(**kwargs)
    lens.add_surface(index=len(element) + 1)
    lens.set_aperture(aperture_type="EPD", value=2.0 * element[0].semi_diam)
    lens.set_field_type(field_type="angle")
    lens.add_field(y=0)
    lens.add_wavelength(value=wavelength_nm / 1000.0, is_primary=True)
    p = lens.paraxial
    f2 = float(p.f2())
    if not math.isfinite(f2) or abs(f2) > 1e14:
        first = {"efl_mm": None, "bfl_mm": None, "ffl_mm": None}
    else:
        # optiland: F2 is measured from the image surface, F1 from the first surface.
        first = {"efl_mm": f2, "bfl_mm": float(p.F2()) + image_distance,
                 "ffl_mm": -float(p.F1())}
    n = len(heights)
    h = np.asarray(heights, dtype=float)
    rays_in = RealRays(x=np.zeros(n), y=h, z=np.full(n, -5.0), L=np.zeros(n), M=np.zeros(n),
                       N=np.ones(n), intensity=np.ones(n),
                       wavelength=np.full(n, wavelength_nm / 1000.0))
    sg = lens.surfaces
    sg.trace(rays_in)
    y, L, M, N = (np.asarray(be.to_numpy(a[-1]), dtype=float) for a in (sg.y, sg.L, sg.M, sg.N))
    rays = []
    for i, hh in enumerate(heights):
        ok = np.isfinite(y[i]) and np.isfinite(N[i])
        rays.append({"height_mm": hh, "y_mm": float(y[i]) if ok else None,
                     "direction": [float(L[i]), float(M[i]), float(N[i])] if ok else None})
    return {**first, "rays": rays}


# ---------------------------------------------------------------------------------------------


def prescription_files() -> list[Path]:
    parts = sorted((ROOT / "scenes" / "parts").glob("*.zmx"))
    tests = sorted((HERE / "test_prescriptions").glob("*.zmx"))
    return parts + tests


def small_ray_focus(numbers: dict, image_distance: float) -> None:
    """Replace the extra tiny-height ray (the last of the fan) by the focal lengths it implies:
    EFL = -h N / M and BFL = image distance - y N / M, the paraxial limit of the real trace."""
    r = numbers["rays"].pop()
    if r["y_mm"] is None or abs(r["direction"][1]) < 1e-18:
        numbers["small_ray"] = {"height_mm": r["height_mm"], "efl_mm": None, "bfl_mm": None}
        return
    _, m, n = r["direction"]
    numbers["small_ray"] = {"height_mm": r["height_mm"], "efl_mm": -r["height_mm"] * n / m,
                            "bfl_mm": image_distance - r["y_mm"] * n / m}


def compute() -> dict:
    entries = []
    for path in prescription_files():
        element, image_distance = lens_surfaces(parse_zmx(path))
        heights = [round(f * element[0].semi_diam, 12) for f in FAN_FRACTIONS]
        heights.append(SMALL_RAY_FRACTION * element[0].semi_diam)
        for wl in WAVELENGTHS_NM:
            entry = {
                "file": str(path.relative_to(ROOT)),
                "wavelength_nm": wl,
                "image_distance_mm": image_distance,
                "rayoptics": rayoptics_numbers(element, image_distance, wl, heights),
                "optiland": optiland_numbers(element, image_distance, wl, heights),
                "numpy_paraxial": paraxial(element, wl / 1000.0),
            }
            for lib in ("rayoptics", "optiland"):
                small_ray_focus(entry[lib], image_distance)
            if any(s.parm[0] != 0.0 for s in element):
                entry["note"] = R2_NOTE
            entries.append(entry)
    return {
        "about": (
            "spibench lens references (validation/lenses/README.md). efl_mm: rear effective "
            "focal length (+ converging). bfl_mm: last lens vertex to the rear paraxial focus, "
            "+ when the focus lies after the vertex. ffl_mm: first lens vertex to the front "
            "paraxial focus, + when the focus lies before the vertex. rays: parallel to the "
            "axis at height_mm in the meridional (y-z) plane, traced to the file's last "
            "surface (the image plane image_distance_mm after the last lens vertex); y_mm is "
            "the intercept there and direction the unit vector (L, M, N) after the last "
            "refraction. null: afocal (no EFL) or a ray that missed."
        ),
        "versions": {k: metadata.version(k) for k in ("rayoptics", "optiland", "numpy")},
        "wavelengths_nm": WAVELENGTHS_NM,
        "fan_fractions_of_semi_diameter": FAN_FRACTIONS,
        "glasses": {
            g: {"sellmeier_b": list(b), "sellmeier_c_um2": list(c), "range_um": list(r),
                "n": {str(wl): sellmeier_index(g, wl / 1000.0) for wl in WAVELENGTHS_NM}}
            for g, (b, c, r) in GLASSES.items()
        },
        "entries": entries,
    }


def agreement(ref: dict) -> dict:
    worst = {"efl_rel": 0.0, "bfl_rel": 0.0, "ffl_rel": 0.0, "y_mm": 0.0, "direction": 0.0,
             "paraxial_vs_numpy_rel": 0.0, "small_ray_vs_numpy_rel": 0.0,
             "small_ray_between_libraries_rel": 0.0}
    for e in ref["entries"]:
        a, b, c = e["rayoptics"], e["optiland"], e["numpy_paraxial"]
        for key in ("efl_mm", "bfl_mm"):
            sa, sb, vc = a["small_ray"][key], b["small_ray"][key], c[key]
            if vc is None:
                continue
            worst["small_ray_vs_numpy_rel"] = max(worst["small_ray_vs_numpy_rel"],
                                                  abs(sa - vc) / abs(vc), abs(sb - vc) / abs(vc))
            worst["small_ray_between_libraries_rel"] = max(
                worst["small_ray_between_libraries_rel"], abs(sa - sb) / abs(vc))
        for key in ("efl", "bfl", "ffl"):
            va, vb, vc = a[key + "_mm"], b[key + "_mm"], c[key + "_mm"]
            if va is None or vb is None:
                assert va is None and vb is None and vc is None, (e["file"], key, va, vb, vc)
                continue
            worst[key + "_rel"] = max(worst[key + "_rel"], abs(va - vb) / abs(vc))
            if "note" not in e:  # the r^2-term file: see R2_NOTE
                worst["paraxial_vs_numpy_rel"] = max(
                    worst["paraxial_vs_numpy_rel"], abs(va - vc) / abs(vc), abs(vb - vc) / abs(vc))
        for ra, rb in zip(a["rays"], b["rays"]):
            assert (ra["y_mm"] is None) == (rb["y_mm"] is None), (e["file"], ra, rb)
            if ra["y_mm"] is None:
                continue
            worst["y_mm"] = max(worst["y_mm"], abs(ra["y_mm"] - rb["y_mm"]))
            worst["direction"] = max(worst["direction"], max(
                abs(p - q) for p, q in zip(ra["direction"], rb["direction"])))
    return worst


def check_agf(path: Path = HERE / "test_catalogue.agf") -> dict:
    """Read the test catalogue's NM/CD/LD records and check each glass's nd against its NM line
    (1e-5) and the Sellmeier entries against GLASSES; returns {name: n_d}."""
    glasses, cur = {}, None
    for line in path.read_text(encoding="ascii").splitlines():
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "NM":
            cur = glasses[tok[1]] = {"formula": int(tok[2]), "nd": float(tok[4])}
        elif tok[0] == "CD":
            cur["cd"] = [float(t) for t in tok[1:]]
        elif tok[0] == "LD":
            cur["ld"] = (float(tok[1]), float(tok[2]))
    out = {}
    for name, g in glasses.items():
        l2 = 0.5875618 ** 2
        c = g["cd"]
        if g["formula"] == 2:  # Sellmeier 1: K1 L1 K2 L2 K3 L3
            n = math.sqrt(1 + sum(c[2 * i] * l2 / (l2 - c[2 * i + 1]) for i in range(3)))
            if name in GLASSES:
                b, cc, rng = GLASSES[name]
                assert tuple(c[0:6:2]) == b and tuple(c[1:6:2]) == cc, name
                assert g["ld"] == rng, name
        elif g["formula"] == 1:  # Schott: A0 + A1 l^2 + A2 l^-2 + A3 l^-4 + A4 l^-6 + A5 l^-8
            n = math.sqrt(c[0] + c[1] * l2 + sum(c[k] * l2 ** (1 - k) for k in range(2, 6)))
        else:
            raise ValueError(f"{name}: formula {g['formula']}")
        assert abs(n - g["nd"]) < 1e-5, (name, n, g["nd"])
        out[name] = n
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true",
                    help="recompute and compare with reference.json instead of writing it")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    ref = compute()
    ref["agreement"] = agreement(ref)
    ref["test_catalogue_nd"] = check_agf()
    # Encodings: the same prescription in six encodings must give the same numbers.
    enc = [e for e in ref["entries"] if Path(e["file"]).name.startswith("enc_")]
    for e in enc:
        twin = next(x for x in enc if x["wavelength_nm"] == e["wavelength_nm"])
        assert e["rayoptics"] == twin["rayoptics"], e["file"]
    print(json.dumps(ref["agreement"], indent=2))
    if args.check:
        old = json.loads(OUT.read_text())
        ok = json.dumps(old["entries"], sort_keys=True) == json.dumps(ref["entries"],
                                                                      sort_keys=True)
        print("reference.json is", "up to date" if ok else "OUT OF DATE")
        return 0 if ok else 1
    OUT.write_text(json.dumps(ref, indent=1) + "\n")
    print(f"wrote {OUT.relative_to(ROOT)}: {len(ref['entries'])} entries")
    return 0


if __name__ == "__main__":
    sys.exit(main())
