#!/usr/bin/env python3
"""The check of `path` against Mitsuba 3.9.1's `path`: Mitsuba XML scenes with indirect light,
converted by `lumis import` (which maps Mitsuba's `path` to lumis' `path`, one light per vertex,
power heuristic), rendered by both renderers over independent seeds at `max_depth` 3 and
unbounded (-1), mean images compared with the race's block test (`race.compare`).

Scenes: a Cornell box (diffuse walls, coloured sides, a ceiling light: colour bleeding is indirect
light); the same box holding a smooth glass sphere (`dielectric`) and a rough one
(`roughdielectric`, GGX α = 0.2) instead of its blocks; glossy metal spheres (`roughconductor`,
GGX α = 0.15, Fresnel 1) on a diffuse floor under the studio environment map (`glossy`); the
Veach MIS scene as the race builds it (four `roughconductor` plates, GGX α 0.005 to 0.1, Fresnel
1, four sphere lights of equal power, a diffuse floor; `veach`).

Run by hand from the repository (scalar_rgb needs no LLVM):
    benches/mitsuba/.venv/bin/python benches/mitsuba/path_check.py --lumis target/release/lumis
"""

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

from race import (REPO, STUDIO, VEACH_CAMERA, VEACH_LIGHTS, VEACH_PLATES, VEACH_ROUGHNESS,
                  compare, look_at, lumis_render, read_exr, write_exr)

BOX = """<scene version="3.0.0">
    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world">
            <lookat origin="0, 1, 3.9" target="0, 1, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="$size"/>
            <integer name="height" value="$size"/>
            <rfilter type="box"/>
        </film>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
    </sensor>
    <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.75, 0.75, 0.75"/></bsdf>
    <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7, 0.1, 0.1"/></bsdf>
    <bsdf type="diffuse" id="green"><rgb name="reflectance" value="0.1, 0.6, 0.1"/></bsdf>
    <shape type="rectangle">
        <transform name="to_world"><rotate x="1" angle="-90"/></transform>
        <ref id="white"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><rotate x="1" angle="90"/><translate y="2"/></transform>
        <ref id="white"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><translate y="1" z="-1"/></transform>
        <ref id="white"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><rotate y="1" angle="90"/><translate x="-1" y="1"/></transform>
        <ref id="red"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><rotate y="1" angle="-90"/><translate x="1" y="1"/></transform>
        <ref id="green"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world">
            <scale x="0.25" y="0.25"/><rotate x="1" angle="90"/><translate y="1.99"/>
        </transform>
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="17, 12, 4"/></emitter>
    </shape>
    $content
</scene>
"""

BLOCKS = """
    <shape type="cube">
        <transform name="to_world">
            <scale x="0.3" y="0.6" z="0.3"/><rotate y="1" angle="20"/><translate x="-0.35" y="0.6" z="-0.3"/>
        </transform>
        <ref id="white"/>
    </shape>
    <shape type="cube">
        <transform name="to_world">
            <scale value="0.3"/><rotate y="1" angle="-20"/><translate x="0.4" y="0.3" z="0.3"/>
        </transform>
        <ref id="white"/>
    </shape>
"""

GLASS = """
    <shape type="sphere">
        <point name="center" x="-0.4" y="0.45" z="-0.2"/>
        <float name="radius" value="0.45"/>
        <bsdf type="dielectric"><string name="int_ior" value="bk7"/></bsdf>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.45" y="0.35" z="0.35"/>
        <float name="radius" value="0.35"/>
        <bsdf type="roughdielectric">
            <string name="distribution" value="ggx"/>
            <float name="alpha" value="0.2"/>
            <float name="int_ior" value="1.5"/>
        </bsdf>
    </shape>
"""


GLOSSY = """<scene version="3.0.0">
    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="45"/>
        <transform name="to_world">
            <lookat origin="0, 1.5, 4" target="0, 0.4, 0" up="0, 1, 0"/>
        </transform>
        <film type="hdrfilm">
            <integer name="width" value="$size"/>
            <integer name="height" value="$size"/>
            <rfilter type="box"/>
        </film>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
    </sensor>
    <bsdf type="twosided" id="metal">
        <bsdf type="roughconductor">
            <string name="distribution" value="ggx"/>
            <float name="alpha" value="0.15"/>
            <string name="material" value="none"/>
        </bsdf>
    </bsdf>
    <bsdf type="twosided" id="floor">
        <bsdf type="diffuse"><rgb name="reflectance" value="0.5, 0.45, 0.4"/></bsdf>
    </bsdf>
    <shape type="sphere">
        <point name="center" x="-0.6" y="0.5" z="0"/>
        <float name="radius" value="0.5"/>
        <ref id="metal"/>
    </shape>
    <shape type="sphere">
        <point name="center" x="0.6" y="0.5" z="0.2"/>
        <float name="radius" value="0.5"/>
        <ref id="metal"/>
    </shape>
    <shape type="rectangle">
        <transform name="to_world"><scale value="4"/><rotate x="1" angle="-90"/></transform>
        <ref id="floor"/>
    </shape>
    <emitter type="envmap">
        <string name="filename" value="studio.exr"/>
        <float name="scale" value="0.8"/>
    </emitter>
</scene>
"""


def veach_template():
    """The race's Veach MIS scene (race.veach) as Mitsuba XML with a `path` integrator."""
    c = VEACH_CAMERA
    matrix = lambda m: " ".join(f"{x:.9g}" for x in m.flatten())
    plates = "".join(f"""
    <shape type="rectangle">
        <transform name="to_world"><matrix value="{matrix(look_at(o, t, (0, 0, -1), (4, 0.55, 1)))}"/></transform>
        <bsdf type="twosided"><bsdf type="roughconductor">
            <string name="distribution" value="ggx"/><float name="alpha" value="{a}"/>
            <string name="material" value="none"/>
        </bsdf></bsdf>
    </shape>""" for (o, t), a in zip(VEACH_PLATES, VEACH_ROUGHNESS))
    lights = "".join(f"""
    <shape type="sphere">
        <point name="center" x="{x}" y="{y}" z="{z}"/><float name="radius" value="{r}"/>
        <bsdf type="diffuse"><rgb name="reflectance" value="0"/></bsdf>
        <emitter type="area"><rgb name="radiance" value="{l}, {l}, {l}"/></emitter>
    </shape>""" for (x, y, z), r, l in VEACH_LIGHTS)
    o, t, u = (", ".join(str(v) for v in c[k]) for k in ("origin", "target", "up"))
    return f"""<scene version="3.0.0">
    <integrator type="path">
        <integer name="max_depth" value="$max_depth"/>
    </integrator>
    <sensor type="perspective">
        <string name="fov_axis" value="y"/>
        <float name="fov" value="{c['fov']}"/>
        <transform name="to_world"><lookat origin="{o}" target="{t}" up="{u}"/></transform>
        <film type="hdrfilm">
            <integer name="width" value="$size"/>
            <integer name="height" value="$size"/>
            <rfilter type="box"/>
        </film>
        <sampler type="independent">
            <integer name="sample_count" value="$spp"/>
        </sampler>
    </sensor>
    <shape type="rectangle">
        <transform name="to_world">
            <scale x="20" y="20" z="1"/><rotate x="1" angle="-90"/><translate y="-4"/>
        </transform>
        <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.2"/></bsdf></bsdf>
    </shape>{plates}{lights}
</scene>
"""


def mitsuba_runs(xml, runs, variant):
    import mitsuba as mi
    mi.set_variant(variant)
    scene = mi.load_file(str(xml))
    return [np.array(mi.render(scene, seed=1000 + s)) for s in range(runs)]


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=REPO / "target" / "path_check")
    p.add_argument("--runs", type=int, default=8, help="seeds per renderer")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--size", type=int, default=96)
    p.add_argument("--block", type=int, default=8, help="block edge (pixels) of the test")
    p.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant")
    p.add_argument("--scenes", default="box,glass,glossy,veach")
    args = p.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    # Lossy compression leaves small negative values in the map, which lumis reads as zero: both
    # renderers get the cleaned map (as import_check.py does).
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    studio = np.nan_to_num(read_exr(STUDIO), nan=0.0, posinf=0.0, neginf=0.0)
    write_exr(args.work / "studio.exr", np.maximum(studio, 0.0))
    ok = True
    for name in args.scenes.split(","):
        template = {"glossy": GLOSSY, "veach": veach_template()}.get(name, BOX)
        content = {"box": BLOCKS, "glass": GLASS, "glossy": "", "veach": ""}[name]
        for depth in [3, -1]:
            text = (template.replace("$content", content).replace("$max_depth", str(depth))
                    .replace("$size", str(args.size)).replace("$spp", str(args.spp)))
            stem = f"{name}_d{depth}".replace("-", "m")
            xml = args.work / f"{stem}.xml"
            xml.write_text(text)
            ron = args.work / f"{stem}.ron"
            result = subprocess.run([str(args.lumis), "import", str(xml), "-o", str(ron)],
                                    capture_output=True, text=True)
            if result.returncode != 0:
                sys.exit(f"lumis import failed:\n{result.stderr}")
            exr = args.work / f"{stem}.exr"
            lumis = [lumis_render(args.lumis, ron, s, exr)[1] for s in range(args.runs)]
            mitsuba = mitsuba_runs(xml, args.runs, args.variant)
            np.save(args.work / f"{stem}_lumis_mean.npy", np.mean(lumis, 0))
            np.save(args.work / f"{stem}_mitsuba_mean.npy", np.mean(mitsuba, 0))
            c = compare(lumis, mitsuba, args.block)
            print(f"{name}, max_depth {depth}: {args.runs} seeds x {args.spp} spp each, "
                  f"{c['blocks']} {args.block}x{args.block}-pixel blocks x channels: "
                  f"max |z| {c['max_z']:.2f} (tolerance {c['z_crit']:.2f}), "
                  f"mean z² {c['mean_z2']:.2f}, image-mean rel. diff "
                  f"{', '.join(f'{x:+.2e}' for x in c['global_rel'])} "
                  f"(|z| {', '.join(f'{x:.2f}' for x in c['global_z'])}, tolerance 3): "
                  f"{'AGREE' if c['ok'] else 'DISAGREE'}", flush=True)
            ok &= c["ok"]
    if not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
