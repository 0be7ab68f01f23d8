#!/usr/bin/env python3
"""The RGB values of Mitsuba 3's named conductors (`material="Au"`), as its RGB variants use them,
for lumis' table (`NAMED_CONDUCTORS` in `plugins/bsdfs/src/fresnel.rs`).

Mitsuba reads each material's spectral η and k (`data/ior/<name>.eta.spd`, `.k.spd`) and, in an
RGB variant, turns each into linear sRGB (`ior_from_file` → `spectrum_list_to_srgb` with
bounded = false and no illuminant): a Riemann sum of the linearly interpolated spectrum times
the CIE 1931 matching functions over 1000 wavelengths evenly spaced in [360, 830] nm (those
outside the data skipped), scaled by (830 − 360) / (1000 · 106.75025939941406), through the
XYZ → linear sRGB matrix, negative channels clamped to 0. This script does that sum itself
(numpy, the matching functions sampled from Mitsuba's `cie1931_xyz`) and checks each value
against the conductor Mitsuba 3.9.1 builds from the name (`mi.traverse` of its `eta`, `k`),
then prints the Rust table. Run by hand:

    DRJIT_LIBLLVM_PATH=... benches/mitsuba/.venv/bin/python benches/mitsuba/named_conductors.py

The spectral data ship with Mitsuba (its `data/ior`, measurements by Palik et al. and
others); lumis keeps only the RGB values this prints.
"""

import sys
from pathlib import Path

import numpy as np

CIE_MIN, CIE_MAX, STEPS = 360.0, 830.0, 1000
Y_NORMALIZATION = 1.0 / 106.7502593994140625
XYZ_TO_SRGB = np.array([[3.240479, -1.537150, -0.498535],
                        [-0.969256, 1.875991, 0.041556],
                        [0.055648, -0.204043, 1.057311]])


def read_spd(path):
    wavelengths, values = [], []
    for line in path.read_text().splitlines():
        line = line.split("#")[0].strip()
        if not line:
            continue
        w, v = line.split()[:2]
        wavelengths.append(float(w))
        values.append(float(v))
    return np.array(wavelengths), np.array(values)


def to_srgb(wavelengths, values, cmf):
    grid = CIE_MIN + np.arange(STEPS) / (STEPS - 1) * (CIE_MAX - CIE_MIN)
    inside = (grid >= wavelengths[0]) & (grid <= wavelengths[-1])
    spectrum = np.interp(grid[inside], wavelengths, values)
    xyz = (cmf[inside] * spectrum[:, None]).sum(0)
    xyz *= (CIE_MAX - CIE_MIN) * Y_NORMALIZATION / STEPS
    return np.maximum(XYZ_TO_SRGB @ xyz, 0.0)


def main():
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    data = Path(mi.__file__).parent / "data" / "ior"
    grid = CIE_MIN + np.arange(STEPS) / (STEPS - 1) * (CIE_MAX - CIE_MIN)
    cmf = np.array([list(mi.cie1931_xyz(float(w))) for w in grid])
    names = sorted(p.name[: -len(".eta.spd")] for p in data.glob("*.eta.spd"))
    rows, worst = [], 0.0
    for name in names:
        eta = to_srgb(*read_spd(data / f"{name}.eta.spd"), cmf)
        k = to_srgb(*read_spd(data / f"{name}.k.spd"), cmf)
        params = mi.traverse(mi.load_dict({"type": "conductor", "material": name}))
        mitsuba = np.array([list(params["eta.value"]), list(params["k.value"])])
        ours = np.array([eta, k])
        difference = np.abs(ours - mitsuba).max() / max(np.abs(mitsuba).max(), 1e-6)
        worst = max(worst, difference)
        rows.append((name, eta, k))
    print(f"// {len(rows)} materials; largest difference from Mitsuba 3.9.1's values: "
          f"{worst:.1e} (relative to the largest channel)", file=sys.stderr)
    for name, eta, k in rows:
        fmt = lambda c: "[" + ", ".join(f"{x:.6}" for x in c) + "]"
        print(f'    ("{name}", {fmt(eta)}, {fmt(k)}),')
    if worst > 1e-5:
        sys.exit("the sums differ from Mitsuba's values")


if __name__ == "__main__":
    main()
