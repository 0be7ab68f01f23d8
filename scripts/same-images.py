#!/usr/bin/env python3
"""Renders every bundled scene with every integrator configuration at a small size and prints a
hash of each render's pixels (every layer of the EXR, decoded: the hash does not depend on how
the file is laid out), so that a refactoring can show it leaves the images bit for bit.

    scripts/same-images.py target/release/lumis before/      # renders, writes before/hashes.txt
    scripts/same-images.py target/release/lumis after/
    scripts/same-images.py --compare before/hashes.txt after/hashes.txt

Needs the Python packages OpenEXR and numpy (`pip install OpenEXR numpy` in a virtual
environment). The scenes are rendered from a copy in the output directory, where the measured
BRDFs they use are generated first; nothing is written into the source tree.
"""

import argparse
import hashlib
import pathlib
import shlex
import shutil
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent

# Each integrator configuration: a name and its --set overrides. Run with and without AOVs: a
# packet of camera samples is shaded together only when no AOV is asked for.
CONFIGS = [
    ("bsdf", ["integrator.type=bsdf"]),
    ("light", ["integrator.type=light"]),
    ("balance", ["integrator.type=balance"]),
    ("power", ["integrator.type=power"]),
    ("max", ["integrator.type=max"]),
    ("cutoff", ["integrator.type=cutoff"]),
    ("alpha", ["integrator.type=alpha"]),
    ("alpha_pre", ["integrator.type=alpha", "integrator.mode=preprocessed", "integrator.alpha_samples=64"]),
    ("alpha_fixed", ["integrator.type=alpha", "integrator.mode=fixed", "integrator.fixed=0.3"]),
    ("exact_alpha", ["integrator.type=exact_alpha"]),
    ("exact_alpha_pre", ["integrator.type=exact_alpha", "integrator.mode=preprocessed",
                         "integrator.alpha_samples=64", "integrator.variance=stratified"]),
    ("cost_alpha", ["integrator.type=cost_alpha", "integrator.cost_ratio=2"]),
    ("pooled_alpha", ["integrator.type=pooled_alpha"]),
    ("pooled_alpha_so", ["integrator.type=pooled_alpha", "integrator.objective=second_order"]),
    ("variance_aware", ["integrator.type=variance_aware"]),
    ("optimal_mis", ["integrator.type=optimal_mis"]),
    ("optimal_mis_prog", ["integrator.type=optimal_mis", "integrator.mode=progressive"]),
]
AOVS = ['integrator.aovs=["alpha", "sampling_variance", "samples"]', "integrator.aovs=[]"]


def scenes(root):
    found = sorted(root.glob("*.ron")) + sorted((root / "paper").glob("*.ron"))
    # plugin.ron needs the example plugin library, built apart.
    return [s for s in found if s.name != "plugin.ron"]


def copy_scenes(lumis, out):
    """A copy of scenes/ in `out` with the measured BRDFs the scenes document (the commands of
    scenes/generate.sh, run with `lumis` and written into the copy, not the source tree)."""
    copy = out / "scenes"
    if copy.exists():
        shutil.rmtree(copy)
    shutil.copytree(ROOT / "scenes", copy, ignore=shutil.ignore_patterns("*.binary"))
    prefix = "//   cargo run --release -- merl "
    commands = sorted({line for ron in scenes(ROOT / "scenes") for line in ron.read_text().splitlines()
                       if line.startswith(prefix)})
    for line in commands:
        args = shlex.split(line[len("//   cargo run --release -- "):])
        target = copy / pathlib.Path(args[-1]).relative_to("scenes")
        target.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([str(lumis)] + args[:-1] + [str(target)], check=True, capture_output=True)
    return copy


def pixel_hash(path):
    import OpenEXR
    import numpy

    digest = hashlib.sha256()
    with OpenEXR.File(str(path), separate_channels=True) as exr:
        for part in exr.parts:
            for name in sorted(part.channels):
                digest.update(name.encode())
                digest.update(numpy.ascontiguousarray(part.channels[name].pixels).tobytes())
    return digest.hexdigest()[:16]


def render_all(lumis, out, quick):
    out.mkdir(parents=True, exist_ok=True)
    lines = []
    spps = [1, 4] if not quick else [4]
    for scene in scenes(copy_scenes(lumis, out)):
        for name, sets in CONFIGS:
            for aov_index, aovs in enumerate(AOVS):
                for spp in spps:
                    tag = f"{scene.parent.name}/{scene.stem} {name} aovs={1 - aov_index} spp={spp}"
                    exr = out / f"{scene.parent.name}-{scene.stem}-{name}-{aov_index}-{spp}.exr"
                    command = [str(lumis), "render", str(scene), "-q", "-o", str(exr), "--spp", str(spp),
                               "--set", "film.width=40", "--set", "film.height=32",
                               "--set", "integrator.samples=8", "--set", aovs]
                    for s in sets:
                        command += ["--set", s]
                    result = subprocess.run(command, capture_output=True, text=True)
                    if result.returncode != 0:
                        lines.append(f"{tag} error {result.stderr.strip().splitlines()[-1]}")
                    else:
                        lines.append(f"{tag} {pixel_hash(exr)}")
                        exr.unlink()
                        exr.with_suffix(".png").unlink(missing_ok=True)
                    print(lines[-1], flush=True)
    (out / "hashes.txt").write_text("\n".join(lines) + "\n")
    shutil.rmtree(out / "scenes")
    print(f"{len(lines)} renders, {sum('error' in l for l in lines)} errors: {out / 'hashes.txt'}")


def compare(a, b):
    before = dict(l.rsplit(" ", 1) for l in pathlib.Path(a).read_text().splitlines() if " error " not in l)
    after = dict(l.rsplit(" ", 1) for l in pathlib.Path(b).read_text().splitlines() if " error " not in l)
    common = sorted(set(before) & set(after))
    differ = [k for k in common if before[k] != after[k]]
    for k in differ:
        print(f"differs: {k}")
    missing = sorted(set(before) ^ set(after))
    for k in missing:
        print(f"only in one: {k}")
    print(f"{len(common) - len(differ)} of {len(common)} renders bit for bit; {len(differ)} differ; "
          f"{len(missing)} in one file only")
    return 1 if differ or missing else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("lumis", nargs="?")
    parser.add_argument("out", nargs="?")
    parser.add_argument("--quick", action="store_true", help="4 spp only (half the renders)")
    parser.add_argument("--compare", nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    if args.compare:
        sys.exit(compare(*args.compare))
    if not args.lumis or not args.out:
        parser.error("give the lumis binary and an output directory, or --compare A B")
    render_all(pathlib.Path(args.lumis).resolve(), pathlib.Path(args.out), args.quick)


if __name__ == "__main__":
    main()
