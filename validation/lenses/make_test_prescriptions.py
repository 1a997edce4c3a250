#!/usr/bin/env python3
"""Write the .zmx test prescriptions and the .agf test catalogue of validation/lenses/.

The files are generated rather than typed so that their bytes (encodings, byte order marks,
line endings, an odd byte count) are exactly what test_prescriptions/README.md says.
Run from anywhere: python3 validation/lenses/make_test_prescriptions.py
Only the standard library is needed. The output is deterministic.
"""

from pathlib import Path

HERE = Path(__file__).resolve().parent
OUT = HERE / "test_prescriptions"
BAD = OUT / "bad"

HEADER = """VERS 120928 0 30221
MODE SEQ
NAME {name}
NOTE 0 spibench test prescription (validation/lenses/test_prescriptions/README.md).
UNIT {unit} X W X CM MR CPMM
ENPD {enpd}
GCAT SCHOTT OHARA
WAVM 1 5.875618E-1 1
PWAV 1
SURF 0
  TYPE STANDARD
  CURV 0.0 0 0 0 0 ""
  DISZ INFINITY
  DIAM 0 0 0 0 1 ""
"""

GLASS_ND_VD = {
    "N-BK7": (1.5168, 64.17),
    "N-BAK1": (1.5725, 57.55),
    "N-SF5": (1.67271, 32.25),
    "N-LAK22": (1.65113, 55.89),
    "S-LAH64": (1.788, 47.37),
}


def surf(n, curv, disz, semi_diam, glass=None, stop=False, conic=None, parms=None,
         kind="STANDARD", extra=()):
    """One SURF block in the operand order Zemax writes (TYPE, CURV, PARM, DISZ, GLAS, CONI, DIAM)."""
    lines = [f"SURF {n}"]
    if stop:
        lines.append("  STOP")
    lines.append(f"  TYPE {kind}")
    lines.append(f'  CURV {curv!r} 0 0 0 0 ""')
    for i, p in enumerate(parms or []):
        lines.append(f"  PARM {i + 1} {p!r}")
    lines.extend(extra)
    if disz is not None:
        lines.append(f"  DISZ {disz!r}")
    if glass is not None:
        nd, vd = GLASS_ND_VD.get(glass, (0, 0))
        lines.append(f"  GLAS {glass} 0 0 {nd} {vd} 0 0 0 0 0 0")
    if conic is not None:
        lines.append(f"  CONI {conic!r}")
    lines.append(f'  DIAM {semi_diam!r} 1 0 0 1 ""')
    return "\n".join(lines) + "\n"


def image(n):
    return f'SURF {n}\n  TYPE STANDARD\n  CURV 0.0 0 0 0 0 ""\n  DISZ 0\n  DIAM 0 0 0 0 1 ""\n'


def prescription(name, surfaces, unit="MM", enpd=10.0):
    text = HEADER.format(name=name, unit=unit, enpd=enpd)
    for s in surfaces:
        text += s
    return text + image(len(surfaces) + 1)


# N-BK7 at the He d line (587.5618 nm) from the Schott Sellmeier coefficients (docs/glasses.md).
N_BK7_D = 1.5168000345005883


def valid_files():
    files = {}
    files["flat_window.zmx"] = prescription("Flat N-BK7 window, 5 mm", [
        surf(1, 0.0, 5.0, 10.0, "N-BK7", stop=True),
        surf(2, 0.0, 10.0, 10.0),
    ], enpd=18.0)
    files["sphere_biconvex.zmx"] = prescription("Biconvex N-BK7 singlet, R = +50/-50 mm", [
        surf(1, 1 / 50.0, 6.0, 12.5, "N-BK7", stop=True),
        surf(2, -1 / 50.0, 45.0, 12.5),
    ], enpd=22.5)
    # Flat front, hyperboloid back with k = -n_d^2: a collimated beam inside the glass is
    # focused without spherical aberration at the d line (the Cartesian surface of a point
    # at infinity in glass imaged into air). Back focal distance -R/(n-1).
    r2 = -25.0
    files["conic_hyperboloid.zmx"] = prescription("Plano-hyperbolic N-BK7 lens, k = -n_d^2", [
        surf(1, 0.0, 8.0, 10.0, "N-BK7", stop=True),
        surf(2, 1 / r2, -r2 / (N_BK7_D - 1.0), 10.0, conic=-(N_BK7_D ** 2)),
    ], enpd=18.0)
    files["conic_paraboloid.zmx"] = prescription("N-BK7 lens with a paraboloidal front, k = -1", [
        surf(1, 1 / 40.0, 5.0, 12.0, "N-BK7", stop=True, conic=-1.0),
        surf(2, -1 / 120.0, 55.0, 12.0),
    ], enpd=21.6)
    files["evenasph_a4_a16.zmx"] = prescription("Even asphere, conic and A4...A16, N-BK7", [
        surf(1, 1 / 20.0, 6.0, 8.0, "N-BK7", stop=True, conic=-0.8, kind="EVENASPH",
             parms=[0.0, 1.0e-5, -2.0e-7, 3.0e-9, -4.0e-11, 5.0e-13, -6.0e-15, 7.0e-17]),
        surf(2, -1 / 60.0, 25.0, 8.0),
    ], enpd=14.4)
    # PARM 1 is the r^2 coefficient: it adds 2*A2 to the paraxial curvature.
    files["evenasph_r2_term.zmx"] = prescription("Even asphere with a non-zero r^2 term (PARM 1)", [
        surf(1, 1 / 25.0, 5.0, 8.0, "N-BK7", stop=True, conic=0.0, kind="EVENASPH",
             parms=[2.0e-3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        surf(2, 0.0, 35.0, 8.0),
    ], enpd=14.4)
    files["cemented_doublet.zmx"] = prescription("Cemented doublet N-BAK1 / N-SF5", [
        surf(1, 1 / 60.0, 5.0, 12.5, "N-BAK1", stop=True),
        surf(2, -1 / 45.0, 2.5, 12.5, "N-SF5"),
        surf(3, -1 / 130.0, 90.0, 12.5),
    ], enpd=22.5)
    files["unit_in.zmx"] = prescription("Plano-convex N-BK7 lens in inches", [
        surf(1, 1 / 2.0, 0.35, 1.0, "N-BK7", stop=True),
        surf(2, 0.0, 3.6, 1.0),
    ], unit="IN", enpd=1.8)
    return files


ENCODING_BASE = prescription("Plano-convex N-BK7, \u00d825.4 mm, f \u2248 50 mm (encoding test)", [
    surf(1, 1 / 25.75, 5.34, 12.7, "N-BK7", stop=True),
    surf(2, 0.0, 46.31, 12.7),
], enpd=22.86).replace("\u2248", "~")


def encoding_files():
    crlf = ENCODING_BASE.replace("\n", "\r\n")
    return {
        "enc_utf16le_bom.zmx": b"\xff\xfe" + crlf.encode("utf-16-le"),
        "enc_utf16be_bom.zmx": b"\xfe\xff" + crlf.encode("utf-16-be"),
        "enc_utf16le_nobom.zmx": crlf.encode("utf-16-le"),
        "enc_utf8.zmx": ENCODING_BASE.encode("utf-8"),
        "enc_utf8_bom.zmx": b"\xef\xbb\xbf" + ENCODING_BASE.encode("utf-8"),
        "enc_iso8859_1.zmx": ENCODING_BASE.encode("iso-8859-1"),
    }


def bad_files():
    ok2 = surf(2, 0.0, 40.0, 10.0)
    files = {}
    files["missing_disz.zmx"] = prescription("Bad: glass surface without DISZ", [
        surf(1, 1 / 30.0, None, 10.0, "N-BK7", stop=True),
        ok2,
    ])
    files["curv_nan.zmx"] = prescription("Bad: non-finite curvature", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True).replace(repr(1 / 30.0) + " 0", "NAN 0"),
        ok2,
    ])
    files["curv_absurd.zmx"] = prescription("Bad: absurd curvature (radius 1e-12 mm)", [
        surf(1, 1.0e12, 5.0, 10.0, "N-BK7", stop=True),
        ok2,
    ])
    files["crossing_surfaces.zmx"] = prescription("Bad: surfaces cross inside the aperture", [
        surf(1, 1 / 20.0, 1.0, 10.0, "N-BK7", stop=True),
        surf(2, -1 / 20.0, 30.0, 10.0),
    ])
    files["aperture_beyond_sphere.zmx"] = prescription("Bad: semi-diameter 12 mm on a sphere of radius 10 mm", [
        surf(1, 1 / 10.0, 12.0, 12.0, "N-BK7", stop=True),
        surf(2, 0.0, 20.0, 12.0),
    ])
    files["aperture_beyond_conic.zmx"] = prescription("Bad: semi-diameter beyond R/sqrt(1+k) of an oblate conic", [
        surf(1, 1 / 10.0, 12.0, 9.0, "N-BK7", stop=True, conic=0.5),
        surf(2, 0.0, 20.0, 9.0),
    ])
    files["unknown_glass_no_ndvd.zmx"] = prescription("Bad: unknown glass, GLAS line without nd/Vd", [
        surf(1, 1 / 30.0, 5.0, 10.0, "NOT-A-GLASS", stop=True),
        ok2,
    ])
    files["unknown_glass_with_ndvd.zmx"] = prescription("Unknown glass whose GLAS line has nd/Vd", [
        surf(1, 1 / 30.0, 5.0, 10.0, "NOT-A-GLASS", stop=True).replace(
            "GLAS NOT-A-GLASS 0 0 0 0", "GLAS NOT-A-GLASS 0 0 1.6 4.5E+1"),
        ok2,
    ])
    files["parm9.zmx"] = prescription("Bad: PARM 9 on an even asphere", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True, kind="EVENASPH",
             parms=[0.0, 1e-5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1e-20]),
        ok2,
    ])
    files["toroidal.zmx"] = prescription("Bad: TYPE TOROIDAL", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True, kind="TOROIDAL"),
        ok2,
    ])
    coordbrk = ('SURF 2\n  TYPE COORDBRK\n  CURV 0.0 0 0 0 0 ""\n  PARM 1 0\n  PARM 2 0.5\n'
                '  PARM 3 2.0\n  PARM 4 0\n  PARM 5 0\n  PARM 6 0\n  DISZ 0\n  DIAM 0 0 0 0 1 ""\n')
    files["coordbrk.zmx"] = prescription("Bad: a coordinate break between the lens surfaces", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True),
        coordbrk,
        surf(3, 0.0, 40.0, 10.0),
    ])
    files["mode_nsc.zmx"] = prescription("Bad: non-sequential file", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True),
        ok2,
    ]).replace("MODE SEQ", "MODE NSC")
    out = {k: v.encode("ascii") for k, v in files.items()}
    # A UTF-16 LE file (byte order mark) with one stray byte at the end: 2k+1 bytes.
    good = prescription("Bad: UTF-16 of odd length", [
        surf(1, 1 / 30.0, 5.0, 10.0, "N-BK7", stop=True), ok2]).replace("\n", "\r\n")
    out["utf16_odd_length.zmx"] = b"\xff\xfe" + good.encode("utf-16-le") + b"\x0a"
    return out


# Zemax AGF text: NM name formula MIL# nd vd exclude-substitution status melt-frequency;
# ED (thermal expansion, density, dPgF, ignore-thermal-expansion); CD coefficients (formula 2,
# Sellmeier 1: K1 L1 K2 L2 K3 L3 with L in um^2; formula 1, Schott: A0 A1 A2 A3 A4 A5);
# TD thermal dispersion; OD cost and resistance classes; LD minimum and maximum wavelength (um).
AGF = """CC spibench test catalogue (validation/lenses/README.md); coefficients from the vendors' catalogues
NM N-SF6HT 2 805254.337 1.80518 25.36 0 1 0
GC
ED 9.0 10.37 3.37 0.0 0
CD 1.77931763E+00 1.33714182E-02 3.38149866E-01 6.17533621E-02 2.08734474E+00 1.74017590E+02 0 0 0 0
TD -4.93E-06 7.02E-09 -2.4E-11 9.84E-07 1.54E-09 0.29 20.0
OD -1 -1 -1 -1 -1 -1
LD 3.7E-01 2.5E+00
NM S-LAH64 2 788474.000 1.788 47.37 0 1 0
GC OHARA S-LAH64
ED 0 0 0 0 0
CD 1.83021453E+00 9.04823290E-03 2.91563590E-01 3.30756689E-02 1.28544024E+00 8.93675501E+01 0 0 0 0
TD 0 0 0 0 0 0 25.0
OD -1 -1 -1 -1 -1 -1
LD 3.2E-01 2.4E+00
NM BK7 1 517642.000 1.5168 64.17 0 2 0
GC legacy Schott BK7, Schott formula
ED 0 0 0 0 0
CD 2.2718929E+00 -1.0108077E-02 1.0592509E-02 2.0816965E-04 -7.6472538E-06 4.9240991E-07 0 0 0 0
TD 0 0 0 0 0 0 20.0
OD -1 -1 -1 -1 -1 -1
LD 3.65E-01 1.014E+00
NM NARROW-BK7 2 517642.000 1.5168 64.17 0 2 0
GC N-BK7 coefficients with a deliberately narrow range: 850 nm lies outside it
ED 0 0 0 0 0
CD 1.03961212E+00 6.00069867E-03 2.31792344E-01 2.00179144E-02 1.01046945E+00 1.03560653E+02 0 0 0 0
TD 0 0 0 0 0 0 20.0
OD -1 -1 -1 -1 -1 -1
LD 4.0E-01 7.0E-01
"""


def main():
    OUT.mkdir(exist_ok=True)
    BAD.mkdir(exist_ok=True)
    for name, text in valid_files().items():
        (OUT / name).write_bytes(text.encode("ascii"))
    for name, data in encoding_files().items():
        (OUT / name).write_bytes(data)
    for name, data in bad_files().items():
        (BAD / name).write_bytes(data)
    (HERE / "test_catalogue.agf").write_bytes(AGF.replace("\n", "\r\n").encode("ascii"))


if __name__ == "__main__":
    main()
