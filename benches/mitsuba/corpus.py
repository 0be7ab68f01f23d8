#!/usr/bin/env python3
"""`lumis import` on public Mitsuba scenes: each scene of Mitsuba's own data repository
(mitsuba-renderer/mitsuba-data: its documentation scenes and its test scenes, written by the
Mitsuba authors) is converted by `lumis import`, rendered by lumis and by Mitsuba 3.9.1
(scalar_rgb) over independent seeds at a small size, and the mean images compared with the
race's block test (race.py `compare`, as import_check.py does).

The scenes stay outside the source tree: `--data` is a checkout of mitsuba-data (cloned with
`git clone --depth 1` into the work folder when absent); the scene folders are copied into the
work folder (default target/mitsuba-corpus) and their film sizes divided there, never in the
checkout. mitsuba-data has no licence file of its own; its scenes are used here to render, not
redistributed.

Two comparisons per scene: against Mitsuba rendering the scene as written (the verdict), and
against Mitsuba with its `direct` integrator, a control: lumis renders `path` where the file asks
for it, so a scene with indirect light must disagree there, which shows that the test resolves
the difference. A scene that does not convert without refusals is still rendered from its
`--partial` conversion and reported as such.

The block test is the race's, with each renderer's pixel variances scaled by its measured
design effect (`design_effect`): Mitsuba's film splats a sample into several pixels under a
Gaussian filter, so its neighbouring pixels covary and a sum of pixel variances understates a
block's.

`--gallery` runs the same comparison on scenes whose licences let their renders be published
(GALLERY: Benedikt Bitterli's "Rendering resources", Mitsuba 0.5 versions, each under its own
Creative Commons licence, as mirrored with their LICENSE.txt files in
jgarciapueyo/mitsuba2-transient-scenes at GALLERY_COMMIT) and writes docs/gallery's side-by-side
images with `--png`. A scene lumis converts only with `--partial` is compared like for like:
Mitsuba renders a copy of the file in which each refused element is replaced as lumis replaced
it (`mirror_partial`), and the gallery says so.

Run through corpus.sh, which sets up the virtual environment and builds lumis.
"""

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from race import REPO, compare, read_exr

# (name, scene file in mitsuba-data, -D defines for both renderers, what it exercises)
SCENES = [
    ("cbox", "scenes/cbox/cbox.xml", {"res": "64"},
     "Cornell box: <include>-free 3.0 file, sampled spectra, Gaussian filter, OBJ meshes"),
    ("cbox-rgb", "docs/scenes/variants_cbox_rgb.xml", {},
     "Cornell box with <path>, sampled spectra, box filter"),
    ("matpreview", "scenes/matpreview/matpreview.xml", {"width": "96", "height": "72"},
     ".serialized meshes (format 3), env map under a general matrix, plastic, checkerboard"),
    ("hello", "scenes/hello.xml", {},
     "PLY teapot without normals (smooth normals), no fov (50 mm focal length), direct"),
    ("veach-mis-direct", "docs/scenes/integrator_direct_both.xml", {},
     "Veach's MIS scene through <include> and <path>, direct integrator"),
    ("veach-mis-lum", "docs/scenes/integrator_direct_lum.xml", {},
     "Veach's MIS scene, emitter sampling only"),
    ("spot", "docs/scenes/emitter_spot_no_texture.xml", {},
     "two spot lights and a constant environment, includes, .serialized (format 4)"),
    ("bunny", "docs/scenes/shape_ply_bunny.xml", {},
     "PLY bunny (smooth normals), twosided diffuse, includes"),
    ("bunny-facet", "docs/scenes/shape_ply_bunny_facet.xml", {},
     "PLY bunny with face_normals"),
    # Mitsuba reads `$spp` here before the included file's <default> for it: given.
    ("sensor-perspective", "docs/scenes/sensor_perspective.xml", {"spp": "16"},
     "perspective sensor with focus_distance, Gaussian filter"),
    ("diffuse-plain", "docs/scenes/bsdf_diffuse_plain.xml", {},
     "material preview: .serialized, rotated env map, checkerboard plane"),
    ("sphere", "docs/scenes/shape_sphere_basic.xml", {}, "sphere shape"),
    ("rectangle", "docs/scenes/shape_rectangle.xml", {}, "rectangle shape"),
    ("disk", "docs/scenes/shape_disk.xml", {}, "disk shape"),
    ("conductor-gold", "docs/scenes/bsdf_conductor_gold.xml", {}, "named conductor (Au)"),
    ("roughconductor-copper", "docs/scenes/bsdf_roughconductor_copper.xml", {},
     "rough named conductor (Cu)"),
]

# The folders of mitsuba-data the scenes and their assets are in.
FOLDERS = ["scenes", "docs/scenes", "common"]

# Scenes whose licences allow their renders to be published: (name, scene file in the gallery
# source, -D defines, what it exercises, licence, credit). The files are Bitterli's Mitsuba 0.5
# versions; the mirror keeps each scene's LICENSE.txt beside it.
GALLERY_SOURCE = "https://github.com/jgarciapueyo/mitsuba2-transient-scenes"
GALLERY_COMMIT = "ab67c4caa9228aa9d4115aeb90c3d3bab0aaf7b5"
GALLERY = [
    ("staircase2", "staircase2/scene.xml", {},
     "Mitsuba 0.5 file, 13 area lights (rectangles, disks), glass, textured rough plastic, "
     "rough conductors, tent filter, `path` (max depth 65)",
     "CC BY 3.0", "'Modern Hall' by NewSee2l035 (blendswap.com/blends/view/51997), Mitsuba "
     "version by Benedikt Bitterli"),
    ("living-room", "living-room/scene.xml", {},
     "Mitsuba 0.5 file, env map, glass, textured diffuse and rough plastic, conductors, "
     "tent filter, `path`; its `mask` BSDF (leaves) is refused",
     "CC BY 3.0", "'The Grey & White Room' by Wig42 (blendswap.com/blends/view/75795), "
     "Mitsuba version by Benedikt Bitterli"),
    ("staircase", "staircase/scene.xml", {},
     "Mitsuba 0.5 file, 774 OBJ meshes, one area light, textured diffuse and rough plastic, "
     "conductors, tent filter, `path`; a `bumpmap` is refused",
     "CC BY 3.0", "'The Wooden Staircase' by Wig42 (blendswap.com/blends/view/77668), "
     "Mitsuba version by Benedikt Bitterli"),
]
GALLERY_FOLDERS = ["staircase2", "living-room", "staircase"]


def shrink(folder, factor):
    """Divides every literal film width and height of the XML files under `folder`."""
    pattern = re.compile(r'(<integer\s+name="(?:width|height)"\s+value=")(\d+)(")')
    for xml in folder.rglob("*.xml"):
        text = xml.read_text()
        new = pattern.sub(lambda m: f"{m[1]}{max(8, int(m[2]) // factor)}{m[3]}", text)
        if new != text:
            xml.write_text(new)


def for_mitsuba3(folder):
    """Mitsuba 0.5's film property `highQualityEdges` (sample outside the film for its edge
    pixels) is neither upgraded nor known by Mitsuba 3.9.1, which refuses the file as an
    unreferenced property: removed from the gallery's copies, so Mitsuba 3 renders without
    border samples, as lumis does (its importer notes the property as ignored)."""
    pattern = re.compile(r'\s*<boolean\s+name="(?:highQualityEdges|high_quality_edges)"[^>]*/>')
    for xml in folder.rglob("*.xml"):
        text = xml.read_text()
        new = pattern.sub("", text)
        if new != text:
            xml.write_text(new)


def plain(folder):
    """Rewrites every XML file under `folder` to what lumis converts in full, keeping geometry,
    lights, camera and filter: every BSDF becomes Mitsuba's default (`diffuse`, 0.5, one-sided
    as Mitsuba's are; lumis' reflect on both sides, which these scenes do not see), textures
    are dropped, and `path` integrators become `direct` (emitter and BSDF sample each)."""
    import xml.etree.ElementTree as ET
    for xml in folder.rglob("*.xml"):
        try:
            tree = ET.parse(xml)
        except ET.ParseError:
            continue
        root = tree.getroot()

        def visit(node):
            for child in list(node):
                if child.tag == "bsdf":
                    keep = {k: v for k, v in child.attrib.items() if k in ("id", "name")}
                    child.clear()
                    child.attrib.update(keep, type="diffuse")
                elif child.tag == "texture" and node is root:
                    node.remove(child)
                elif child.tag == "integrator" and (
                        child.get("type") in ("path", "moment")
                        or child.get("type", "").startswith("$")):
                    child.clear()
                    child.attrib["type"] = "direct"
                else:
                    visit(child)
        visit(root)
        tree.write(xml)


def element_span(lines, line):
    """The (first, last) line indices (0-based, inclusive) of the XML element that starts on
    1-based line `line`: from its first tag to its closing tag, found by counting tags."""
    tag = re.compile(r"<(/?)([A-Za-z_][\w.-]*)[^>]*?(/?)>|<!--.*?-->", re.S)
    text = "\n".join(lines[line - 1:])
    depth = 0
    for m in tag.finditer(text):
        if m.group(0).startswith("<!--"):
            continue
        if m[1]:
            depth -= 1
        elif not m[3]:
            depth += 1
        if depth == 0:
            return line - 1, line - 1 + text.count("\n", 0, m.end())
    raise ValueError(f"line {line}: no complete element")


def mirror_partial(problems):
    """Edits the scene files so that Mitsuba renders what `lumis import --partial` converted:
    each refusal ("skipped: FILE:LINE: reason") is mirrored as lumis handled it. A refused BSDF
    becomes Mitsuba's default (`diffuse`, keeping its `id`), as lumis gives its shapes; a `<ref>`
    that lumis could not resolve is removed (its shape gets the default BSDF in both); an unused
    top-level element changes nothing; a refusal inside a refused BSDF goes with it. Returns the
    refusals it cannot mirror (then the scene is not compared)."""
    parsed, unmirrored = [], []
    for problem in problems:
        m = re.match(r"skipped: (.+?):(\d+): (.*)$", problem)
        if m:
            parsed.append((Path(m[1]), int(m[2]), m[3], problem))
        else:
            unmirrored.append(problem)
    files = {path: path.read_text().split("\n") for path, _, _, _ in parsed}
    edits, inner = {}, []
    for path, line, reason, problem in parsed:
        if re.match(r"BSDF `\w+` is not converted", reason):
            edits.setdefault(path, []).append((element_span(files[path], line), "bsdf"))
        elif reason.startswith("reference to `") and "names nothing" in reason:
            edits.setdefault(path, []).append((element_span(files[path], line), "remove"))
        elif "never used" in reason:
            pass
        else:
            inner.append((path, line, problem))
    for path, line, problem in inner:
        if not any(first < line - 1 <= last and action == "bsdf"
                   for (first, last), action in edits.get(path, [])):
            unmirrored.append(problem)
    for path, spans in edits.items():
        lines = files[path]
        for (first, last), action in sorted(spans, reverse=True):
            head = lines[first]
            if action == "bsdf":
                attrs = "".join(f' {k}="{v[1]}"' for k in ("id", "name")
                                if (v := re.search(rf'\s{k}="([^"]*)"', head)))
                lines[first:last + 1] = [f'<bsdf type="diffuse"{attrs}/>']
            else:
                lines[first:last + 1] = []
        path.write_text("\n".join(lines))
    return unmirrored


def lumis_runs(binary, ron, runs, spp, exr):
    images = []
    for s in range(runs):
        result = subprocess.run([str(binary), "render", str(ron), "--seed", str(s), "--spp",
                                 str(spp), "--quiet", "-o", str(exr)],
                                capture_output=True, text=True)
        if result.returncode != 0:
            raise RuntimeError(result.stderr.strip())
        images.append(read_exr(exr))
    return images


def mitsuba_runs(xml, defines, runs, spp, integrator):
    import mitsuba as mi
    scene = mi.load_file(str(xml), **defines)
    kwargs = {} if integrator is None else {"integrator": mi.load_dict({"type": integrator})}
    return [np.array(mi.render(scene, seed=1000 + s, spp=spp, **kwargs)) for s in range(runs)]


def design_effect(runs, block):
    """How much more the block means of `runs` (one image per seed) vary across seeds than
    their pixels' variances alone say. A renderer that splats a sample into several pixels
    (Mitsuba's film with a Gaussian or tent filter) makes neighbouring pixels covary, and the
    race's test, which sums pixel variances, then underestimates a block's variance; lumis
    samples its filter by importance, so its pixels are independent (factor 1).

    Per block, r = (variance of the block mean across the k runs) / (Σ pixel variances / n²)
    is the factor times a χ²(k − 1)/(k − 1) variable; the factor is the median of r over every
    block divided by that variable's median (robust to the heavy tails of path-traced pixels,
    which make a pooled ratio unstable at 4 runs), and at least 1."""
    x = np.stack(runs).astype(np.float64)
    k, h, w = len(x), x.shape[1] // block * block, x.shape[2] // block * block
    x = x[:, :h, :w]
    pixels = x.var(0, ddof=1).reshape(h // block, block, w // block, block, 3).sum((1, 3))
    means = x.reshape(k, h // block, block, w // block, block, 3).mean((2, 4))
    blocks = means.var(0, ddof=1) * block ** 4
    ratios = blocks[pixels > 0] / pixels[pixels > 0]
    if ratios.size == 0:
        return 1.0
    # The median of χ²(k − 1)/(k − 1), from a fixed-seed sample (to 0.1 %).
    chi2_median = np.median(np.random.default_rng(0).chisquare(k - 1, 1_000_000)) / (k - 1)
    return max(1.0, float(np.median(ratios) / chi2_median))


def compare_correlated(runs_a, runs_b, block):
    """The race's block test with each renderer's pixel variances scaled by its design effect
    (each run's deviation from the mean image stretched by its square root: the means are
    unchanged); the factors are returned with the result."""
    def widened(runs):
        d = design_effect(runs, block)
        mean = np.mean(runs, 0)
        return [mean + np.sqrt(d) * (r - mean) for r in runs], d
    a, d_a = widened(runs_a)
    b, d_b = widened(runs_b)
    c = compare(a, b, block)
    c["design_effect"] = (d_a, d_b)
    c["uncorrected"] = compare(runs_a, runs_b, block)
    return c


def verdict(c):
    return (f"{'AGREE' if c['ok'] else 'DISAGREE'} (max |z| {c['max_z']:.2f} of "
            f"{c['z_crit']:.2f} over {c['blocks']} blocks, image-mean |z| "
            f"{max(c['global_z']):.2f}, rel. L1 {c['rel_l1']:.2%}; design effects lumis "
            f"{c['design_effect'][0]:.2f}, Mitsuba {c['design_effect'][1]:.2f}; without them "
            f"max |z| {c['uncorrected']['max_z']:.2f}, image-mean |z| "
            f"{max(c['uncorrected']['global_z']):.2f})")


def to_png(rgb, path):
    """A linear image as an sRGB PNG (clamped), for the gallery."""
    import mitsuba as mi
    bitmap = mi.Bitmap(np.ascontiguousarray(rgb.astype(np.float32)))
    bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(
        str(path))


def side_by_side(left, right, path, gap=2):
    """lumis | Mitsuba in one sRGB PNG, each at half the tested resolution (2 × 2 pixel means,
    so that the file stays a few tens of KB), a white gap between them."""
    import mitsuba as mi

    def half(x):
        h, w = x.shape[0] // 2 * 2, x.shape[1] // 2 * 2
        return x[:h, :w].reshape(h // 2, 2, w // 2, 2, 3).mean((1, 3))
    left, right = half(left), half(right)
    both = np.concatenate([left, np.ones((left.shape[0], gap, 3)), right], 1)
    bitmap = mi.Bitmap(np.ascontiguousarray(both.astype(np.float32)))
    bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True).write(
        str(path))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=REPO / "target" / "mitsuba-corpus")
    p.add_argument("--data", type=Path, help="a checkout of mitsuba-data, or with --gallery of "
                   "GALLERY_SOURCE at GALLERY_COMMIT (default: cloned into WORK when absent)")
    p.add_argument("--gallery", action="store_true",
                   help="the licensed scenes of GALLERY instead of mitsuba-data's; with --png, "
                        "one side-by-side image (lumis | Mitsuba) per scene")
    p.add_argument("--runs", type=int, default=8, help="seeds per renderer")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel of each run")
    p.add_argument("--shrink", type=int, default=6, help="divides literal film sizes")
    p.add_argument("--block", type=int, default=8, help="block edge (pixels) of the test")
    p.add_argument("--only", nargs="*", help="scene names to run (default: all)")
    p.add_argument("--png", type=Path, help="write lumis' and Mitsuba's mean images here")
    p.add_argument("--plain", action="store_true",
                   help="compare the scenes with every BSDF made diffuse and `path` made "
                        "`direct` (what lumis converts in full), not as written")
    args = p.parse_args()
    work = args.work.resolve()
    work.mkdir(parents=True, exist_ok=True)
    if args.gallery:
        scenes = [(n, f, d, w) for n, f, d, w, _, _ in GALLERY]
        data, folders = args.data or work / "gallery-data", GALLERY_FOLDERS
        if not data.exists():
            subprocess.run(["git", "clone", GALLERY_SOURCE, str(data)], check=True)
            subprocess.run(["git", "-C", str(data), "checkout", GALLERY_COMMIT], check=True)
    else:
        scenes = SCENES
        data, folders = args.data or work / "mitsuba-data", FOLDERS
        if not data.exists():
            subprocess.run(["git", "clone", "--depth", "1",
                            "https://github.com/mitsuba-renderer/mitsuba-data", str(data)],
                           check=True)
    tree = work / "tree"
    if tree.exists():
        shutil.rmtree(tree)
    for folder in folders:
        shutil.copytree(data / folder, tree / folder)
    shrink(tree, args.shrink)
    if args.gallery:
        for_mitsuba3(tree)
    if args.plain:
        plain(tree)

    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    results = []
    for name, scene, defines, what in scenes:
        if args.only and name not in args.only:
            continue
        xml = tree / scene
        out = work / name
        out.mkdir(exist_ok=True)
        ron = out / "scene.ron"
        d = [x for k, v in defines.items() for x in ("-D", f"{k}={v}")]
        strict = subprocess.run([str(args.lumis), "import", str(xml), "-o", str(ron), *d],
                                capture_output=True, text=True)
        partial = strict
        if strict.returncode != 0:
            partial = subprocess.run([str(args.lumis), "import", str(xml), "-o", str(ron), *d,
                                      "--partial"], capture_output=True, text=True)
        lines = partial.stderr.strip().splitlines()
        problems = [l for l in lines if l.startswith(("skipped:", "error:"))]
        notes = [l for l in lines if l.startswith("note:")]
        r = {"name": name, "scene": scene, "what": what, "imports": strict.returncode == 0,
             "converts": ron.exists() and partial.returncode == 0,
             "problems": problems, "notes": notes}
        print(f"== {name} ({scene}): {what}")
        print(f"   import: {'no refusal' if r['imports'] else f'{len(problems)} refusal(s)'}"
              f", {len(notes)} note(s)")
        for line in problems:
            print(f"     {line}")
        if r["converts"] and not r["imports"]:
            # Mitsuba renders what lumis converted: the refusals mirrored in its copy.
            r["unmirrored"] = mirror_partial(problems)
            for line in r["unmirrored"]:
                print(f"   not mirrored for Mitsuba, not compared: {line}")
        if r["converts"] and not r.get("unmirrored"):
            exr = out / "lumis.exr"
            try:
                lumis = lumis_runs(args.lumis, ron, args.runs, args.spp, exr)
            except RuntimeError as e:
                r["render_error"] = str(e)
                print(f"   lumis render failed: {e}")
                results.append(r)
                continue
            mi_defines = {k: v for k, v in defines.items()}
            # The control (Mitsuba's `direct`) shows that the test resolves indirect light; the
            # gallery's scenes are lit mostly indirectly, and it is left out there.
            labels = [("as written", None)] + ([] if args.gallery else [("direct", "direct")])
            for label, integrator in labels:
                try:
                    mitsuba = mitsuba_runs(xml, mi_defines, args.runs, args.spp, integrator)
                except Exception as e:  # Mitsuba refuses the scene: reported, not fatal.
                    r[label] = f"Mitsuba failed: {e}"
                    print(f"   vs Mitsuba {label}: Mitsuba failed: {e}")
                    continue
                if mitsuba[0].shape != lumis[0].shape:
                    r[label] = f"sizes differ: {mitsuba[0].shape} vs {lumis[0].shape}"
                    print(f"   vs Mitsuba {label}: {r[label]}")
                    continue
                c = compare_correlated(lumis, mitsuba, args.block)
                r[label] = {"ok": c["ok"], "max_z": c["max_z"], "z_crit": c["z_crit"],
                            "global_z": c["global_z"], "rel_l1": c["rel_l1"],
                            "global_rel": c["global_rel"], "mean_z2": c["mean_z2"],
                            "design_effect": c["design_effect"],
                            "uncorrected_max_z": c["uncorrected"]["max_z"],
                            "uncorrected_global_z": c["uncorrected"]["global_z"]}
                print(f"   vs Mitsuba {label}: {verdict(c)}")
                if args.png and label == "as written" and args.gallery:
                    args.png.mkdir(parents=True, exist_ok=True)
                    side_by_side(np.mean(lumis, 0), np.mean(mitsuba, 0),
                                 args.png / f"{name}.png")
                elif args.png and label == "as written":
                    args.png.mkdir(parents=True, exist_ok=True)
                    to_png(np.mean(lumis, 0), args.png / f"{name}-lumis.png")
                    to_png(np.mean(mitsuba, 0), args.png / f"{name}-mitsuba.png")
        results.append(r)
    (work / "results.json").write_text(json.dumps(results, indent=1))
    n = len(results)
    imported = sum(r["imports"] for r in results)
    converted = sum(r["converts"] for r in results)
    agree = {label: sum(isinstance(r.get(label), dict) and r[label]["ok"] for r in results)
             for label in ["as written", "direct"]}
    compared = {label: sum(isinstance(r.get(label), dict) for r in results)
                for label in ["as written", "direct"]}
    print(f"\n{n} scenes: {imported} import without refusal, {converted} convert with "
          f"--partial; agree with Mitsuba as written in {agree['as written']} of "
          f"{compared['as written']} compared, with Mitsuba `direct` in {agree['direct']} of "
          f"{compared['direct']}")


if __name__ == "__main__":
    sys.exit(main())
