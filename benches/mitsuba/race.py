#!/usr/bin/env python3
"""lumis against Mitsuba 3 at equal samples: the same scenes written for both renderers, the mean
images checked for agreement within their noise, then both renderers timed over interleaved runs.

Run through race.sh, which sets up the virtual environment and builds lumis. See
docs/performance.md for the method; `race.py --help` for the options.

Conventions made equal here (each checked by the image comparison):
- camera: both take the vertical field of view (Mitsuba `fov_axis: y`) and the same look-at frame;
  both filter with a box over the pixel (Mitsuba's default is a Gaussian);
- integrators: lumis `power` with `samples: 2` takes, per light, one BSDF and one light sample per
  camera sample; Mitsuba `direct` with emitter_samples = bsdf_samples = 1 takes one of each for
  the whole scene, choosing ONE light per light sample. With one light (Cornell, dragon) the work
  is the same; for Veach (four lights) Mitsuba is also timed with 4 + 4 samples, the same rays;
- materials: `diffuse` in both (Mitsuba's wrapped in `twosided`, as lumis surfaces are two-sided);
  lumis `glossy` with specular 1 and diffuse 0 (Schlick with F0 = 1 is exactly 1) against Mitsuba
  `roughconductor` (GGX, material `none`: eta 0, k 1, Fresnel exactly 1). They differ in the
  masking term only: lumis uses the height-correlated Smith G2, Mitsuba the separable product,
  a relative difference of Λ(ωo)Λ(ωi)/((1+Λ(ωo))(1+Λ(ωi))), under 1e-3 at the Veach plates' angles
  and roughnesses (printed by the script);
- environment: Mitsuba interpolates its map bilinearly between texels placed at the grid's
  vertices, lumis holds one constant radiance per pixel. Mitsuba gets the source map; lumis gets
  the map Mitsuba evaluates, sampled at the centres of cells half a texel wide, each cell inside
  one bilinear patch, so that every cell carries exactly Mitsuba's average radiance over it;
- meshes: flat shaded in both (lumis ignores nothing it is given, so the dragon is written without
  vertex normals): the two renderers treat shading normals that disagree with the geometric one
  differently, and the race is about speed, not about that convention.

Why one file of over 600 lines: the race's stages (writing each scene for both renderers, the
agreement check, the timing) share the scene conversions and run records.
"""

import argparse
import json
import math
import os
import shutil
import statistics
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
# The paired-ratio interval of the interleaved rounds, as benches/ab.py computes it.
sys.path.insert(0, str(HERE.parent))
from ab import fmt_ratio, ratio_interval  # noqa: E402
SHARED_DRAGON = REPO.parent / "shared" / "data" / "meshes" / "dragon_res2.glb"
STUDIO = REPO / "scenes" / "envmaps" / "studio.exr"


# ---------------------------------------------------------------------------------------------
# Transforms, as lumis builds them (core/src/scene/shapes.rs): scale, then rotations, then
# translation; look_at with columns (up × dir, dir × right, dir, origin), as Mitsuba's look_at.


def rotation(axis, degrees):
    x, y, z = np.asarray(axis, float) / np.linalg.norm(axis)
    quarter = degrees / 90.0
    if quarter == round(quarter):
        s, c = [(0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 0.0)][int(round(quarter)) % 4]
    else:
        s, c = math.sin(math.radians(degrees)), math.cos(math.radians(degrees))
    t = 1.0 - c
    m = np.eye(4)
    m[:3, :3] = [
        [c + t * x * x, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, c + t * y * y, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, c + t * z * z],
    ]
    return m


def transform(scale=(1, 1, 1), rotate=(), translate=(0, 0, 0)):
    m = np.diag([*scale, 1.0])
    for axis, angle in rotate:
        m = rotation(axis, angle) @ m
    t = np.eye(4)
    t[:3, 3] = translate
    return t @ m


def look_at(origin, target, up, scale=(1, 1, 1)):
    origin, target, up = (np.asarray(v, float) for v in (origin, target, up))
    d = (target - origin) / np.linalg.norm(target - origin)
    right = np.cross(up, d)
    right /= np.linalg.norm(right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, np.cross(d, right), d, origin
    return m @ np.diag([*scale, 1.0])


# ---------------------------------------------------------------------------------------------
# Scenes in one neutral form, written out for each renderer.


def cornell():
    white, red, green = (0.725, 0.71, 0.68), (0.63, 0.065, 0.05), (0.14, 0.45, 0.091)
    rect = lambda bsdf, **t: dict(shape="rectangle", bsdf=bsdf, matrix=transform(**t))
    return dict(
        name="cornell",
        camera=dict(origin=(278, 273, -800), target=(278, 273, -799), up=(0, 1, 0), fov=39.3077),
        size=(256, 256),
        spp=64,
        bsdfs=dict(
            white=("diffuse", white), red=("diffuse", red), green=("diffuse", green),
            light=("diffuse", (0.78, 0.78, 0.78)),
        ),
        shapes=[
            rect("white", scale=(278, 279.6, 1), rotate=[((1, 0, 0), -90)], translate=(278, 0, 279.6)),
            rect("white", scale=(278, 279.6, 1), rotate=[((1, 0, 0), 90)], translate=(278, 548.8, 279.6)),
            rect("white", scale=(278, 274.4, 1), rotate=[((0, 1, 0), 180)], translate=(278, 274.4, 559.2)),
            rect("red", scale=(279.6, 274.4, 1), rotate=[((0, 1, 0), -90)], translate=(556, 274.4, 279.6)),
            rect("green", scale=(279.6, 274.4, 1), rotate=[((0, 1, 0), 90)], translate=(0, 274.4, 279.6)),
            dict(shape="cube", bsdf="white",
                 matrix=transform((82.5, 82.5, 82.5), [((0, 1, 0), -16.6)], (185.5, 82.5, 169))),
            dict(shape="cube", bsdf="white",
                 matrix=transform((82.5, 165, 82.5), [((0, 1, 0), 17.2)], (368.5, 165, 351.25))),
            dict(shape="rectangle", bsdf="light", radiance=(17, 12, 4),
                 matrix=transform((65, 52.5, 1), [((1, 0, 0), 90)], (278, 548.7, 279.5))),
        ],
    )


VEACH_ROUGHNESS = (0.005, 0.02, 0.05, 0.1)
VEACH_PLATES = [
    ((0, -1.2, 1.5), (0, -0.305, 1.9461)),
    ((0, -1.65, 2.9), (0, -0.7128, 3.2488)),
    ((0, -2.1, 4.3), (0, -1.1347, 4.5611)),
    ((0, -2.55, 5.7), (0, -1.5658, 5.877)),
]
# Radii 0.1, 0.2, 0.45, 0.9 instead of 0.0333, 0.1, 0.3, 0.9, with the same power (radiance
# 1/r²): Mitsuba computes a sphere light's cone density 1/(2π(1 − cos θmax)) in f32 with
# cancellation, off by up to 1.5 % for the smallest sphere seen from the far floor
# (sin²θmax = 3.9e-6), which biases its image there by about 0.3 % (the check sees it, z ≈ 7).
VEACH_LIGHTS = [((3.75, 4.5, -1), 0.1, 100.0), ((1.25, 4.5, -1), 0.2, 25.0),
                ((-1.25, 4.5, -1), 0.45, 4.938), ((-3.75, 4.5, -1), 0.9, 1.235)]
VEACH_CAMERA = dict(origin=(0, 2, 15), target=(0, -1.5, 2.5), up=(0, 1, 0), fov=28)


def veach():
    """scenes/veach.ron with plates Mitsuba can also render (specular 1, diffuse 0) and larger
    lights (see VEACH_LIGHTS)."""
    bsdfs = {f"plate{i}": ("glossy", a) for i, a in enumerate(VEACH_ROUGHNESS)}
    bsdfs.update(floor=("diffuse", (0.2, 0.2, 0.2)), black=("diffuse", (0, 0, 0)))
    shapes = [
        dict(shape="rectangle", bsdf=f"plate{i}",
             matrix=look_at(o, t, (0, 0, -1), scale=(4, 0.55, 1)))
        for i, (o, t) in enumerate(VEACH_PLATES)
    ]
    shapes.append(dict(shape="rectangle", bsdf="floor",
                       matrix=transform((20, 20, 1), [((1, 0, 0), -90)], (0, -4, 0))))
    shapes += [dict(shape="sphere", bsdf="black", center=c, radius=r, radiance=(l, l, l))
               for c, r, l in VEACH_LIGHTS]
    return dict(name="veach", camera=VEACH_CAMERA, size=(320, 240), spp=64, bsdfs=bsdfs,
                shapes=shapes)


# The dragon mesh is 0.2 units long; the scene is scaled up so that Mitsuba's ray offsets
# (relative to 1 + |p|, tuned for unit-sized scenes) do not leak light through its fine detail.
DRAGON_SCALE = 10.0


def dragon():
    k = DRAGON_SCALE
    return dict(
        name="dragon",
        # Looking down, so that the floor hides the map: seen directly, Mitsuba's bilinear map
        # and lumis's constant cells differ at the scale of a pixel (the check sees it); the
        # lighting integrates them over cells, where they agree.
        camera=dict(origin=(0.2, 3, 3), target=(-0.06, 1.1, 0), up=(0, 1, 0), fov=30),
        size=(320, 240),
        spp=64,
        bsdfs=dict(jade=("diffuse", (0.3, 0.6, 0.4)), floor=("diffuse", (0.5, 0.5, 0.5))),
        shapes=[
            dict(shape="mesh", bsdf="jade", file="dragon"),
            dict(shape="rectangle", bsdf="floor",
                 matrix=transform((30, 30, 1), [((1, 0, 0), -90)], (0, 0.0527392 * k, 0))),
        ],
        envmap="studio",
    )


def glossy_masking_difference():
    """The largest relative difference between the height-correlated and the separable Smith
    masking at the Veach plates' centres, for the camera and light directions of each plate."""
    worst = 0.0
    for (origin, target), alpha in zip(VEACH_PLATES, VEACH_ROUGHNESS):
        o, t = np.asarray(origin, float), np.asarray(target, float)
        n = (t - o) / np.linalg.norm(t - o)
        lam = lambda w: (math.sqrt(1 + alpha**2 * (1 / np.dot(n, w) ** 2 - 1)) - 1) / 2
        wo = np.asarray(VEACH_CAMERA["origin"], float) - o
        for c, _, _ in VEACH_LIGHTS:
            wi = np.asarray(c, float) - o
            lo, li = lam(wo / np.linalg.norm(wo)), lam(wi / np.linalg.norm(wi))
            worst = max(worst, lo * li / ((1 + lo) * (1 + li)))
    return worst


# ---------------------------------------------------------------------------------------------
# Assets: the flat-shaded dragon (PLY for Mitsuba, GLB for lumis) and the environment maps.


def read_glb_mesh(path):
    data = path.read_bytes()
    json_len = struct.unpack_from("<I", data, 12)[0]
    doc = json.loads(data[20:20 + json_len])
    bin_start = 20 + json_len + 8
    prim = doc["meshes"][0]["primitives"][0]

    def accessor(i, dtype, width):
        acc = doc["accessors"][i]
        view = doc["bufferViews"][acc["bufferView"]]
        if view.get("byteStride", 0) not in (0, width * np.dtype(dtype).itemsize):
            sys.exit(f"{path}: interleaved buffers are not supported here")
        start = bin_start + view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        count = acc["count"] * width
        return np.frombuffer(data, dtype=dtype, count=count, offset=start).reshape(-1, width)

    positions = accessor(prim["attributes"]["POSITION"], "<f4", 3)
    index_type = {5125: "<u4", 5123: "<u2"}[doc["accessors"][prim["indices"]]["componentType"]]
    indices = accessor(prim["indices"], index_type, 1).reshape(-1, 3).astype("<u4")
    return positions, indices


def write_glb_mesh(path, positions, indices):
    pos, idx = positions.astype("<f4").tobytes(), indices.astype("<u4").tobytes()
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(pos) + len(idx)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
                        {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
             "min": positions.min(0).tolist(), "max": positions.max(0).tolist()},
            {"bufferView": 1, "componentType": 5125, "count": indices.size, "type": "SCALAR"},
        ],
    }
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    body = pos + idx
    chunks = (struct.pack("<I4s", len(text), b"JSON") + text
              + struct.pack("<I4s", len(body), b"BIN\0") + body)
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)


def write_ply_mesh(path, positions, indices):
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(positions)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(indices)}\nproperty list uchar int vertex_indices\nend_header\n")
    faces = np.empty(len(indices), dtype=[("n", "u1"), ("i", "<i4", 3)])
    faces["n"], faces["i"] = 3, indices
    path.write_bytes(header.encode() + positions.astype("<f4").tobytes() + faces.tobytes())


def lumis_envmap_from_mitsuba(src):
    """The radiance Mitsuba's envmap gives (bilinear between texels at the grid vertices, after
    its half-texel shift), sampled at the centres of lumis cells half a texel wide, each inside
    one bilinear patch. lumis's u is Mitsuba's plus ½ (its map centre looks toward −z)."""
    h, w, _ = src.shape
    padded = np.concatenate([src, src[:, :1]], axis=1)  # Mitsuba's periodic column
    out_w, out_h = 2 * w, 2 * (h - 1)
    u = (np.arange(out_w) + 0.5) / out_w
    v = (np.arange(out_h) + 0.5) / out_h
    x = (((u - 0.5) - 0.5 / w) % 1.0) * w
    y = v * (h - 1)
    x0, y0 = np.minimum(x.astype(int), w - 1), np.minimum(y.astype(int), h - 2)
    fx, fy = (x - x0)[None, :, None], (y - y0)[:, None, None]
    p = lambda dy, dx: padded[(y0 + dy)[:, None], (x0 + dx)[None, :]]
    return ((1 - fy) * ((1 - fx) * p(0, 0) + fx * p(0, 1))
            + fy * ((1 - fx) * p(1, 0) + fx * p(1, 1))).astype(np.float32)


def write_exr(path, rgb):
    import mitsuba as mi
    mi.Bitmap(np.ascontiguousarray(rgb, dtype=np.float32),
              pixel_format=mi.Bitmap.PixelFormat.RGB).write(str(path))


def read_exr(path):
    import mitsuba as mi
    return np.array(mi.Bitmap(str(path)).convert(mi.Bitmap.PixelFormat.RGB,
                                                 mi.Struct.Type.Float32, False))


def prepare_assets(work, scenes):
    """Writes the meshes and maps the scenes need into `work` (Mitsuba variant irrelevant)."""
    import mitsuba as mi
    mi.set_variant("scalar_rgb")
    names = {s["name"] for s in scenes}
    if "dragon" in names:
        positions, indices = read_glb_mesh(SHARED_DRAGON)
        positions = positions * np.float32(DRAGON_SCALE)
        write_glb_mesh(work / "dragon.glb", positions, indices)
        write_ply_mesh(work / "dragon.ply", positions, indices)
        # Lossy compression leaves small negative values, which lumis reads as zero: give both
        # renderers the cleaned map.
        src = np.nan_to_num(read_exr(STUDIO), nan=0.0, posinf=0.0, neginf=0.0)
        src = np.maximum(src, 0.0)
        write_exr(work / "studio_mitsuba.exr", src)
        write_exr(work / "studio_lumis.exr", lumis_envmap_from_mitsuba(src))


# ---------------------------------------------------------------------------------------------
# Writers.


def ron_matrix(m):
    return "(" + ", ".join(f"{v:.9g}" for v in m.reshape(-1)) + ")"


def write_lumis_scene(scene, work):
    c = scene["camera"]
    lines = [
        "Scene(",
        f"    camera: (position: {tuple(c['origin'])}, target: {tuple(c['target'])}, "
        f"up: {tuple(c['up'])}, fov: {c['fov']}),",
        f"    film: (width: {scene['size'][0]}, height: {scene['size'][1]}),",
        f"    sampler: (spp: {scene['spp']}, seed: 0),",
        '    integrator: (type: "power", samples: 2),',
        "    bsdfs: {",
    ]
    for name, (kind, value) in scene["bsdfs"].items():
        if kind == "diffuse":
            lines.append(f'        "{name}": (type: "diffuse", reflectance: {tuple(value)}),')
        else:
            lines.append(f'        "{name}": (type: "glossy", roughness: {value}, '
                         "specular: 1, diffuse: 0),")
    lines += ["    },", "    shapes: ["]
    for s in scene["shapes"]:
        emitter = (f', emitter: (type: "area", radiance: {tuple(s["radiance"])})'
                   if "radiance" in s else "")
        if s["shape"] == "sphere":
            geo = f'type: "sphere", center: {tuple(s["center"])}, radius: {s["radius"]}'
        elif s["shape"] == "mesh":
            geo = f'type: "gltf", file: "{s["file"]}.glb"'
        else:
            geo = f'type: "{s["shape"]}", transform: (matrix: {ron_matrix(s["matrix"])})'
        lines.append(f'        ({geo}, bsdf: "{s["bsdf"]}"{emitter}),')
    lines.append("    ],")
    if "envmap" in scene:
        lines.append(f'    emitters: [(type: "envmap", file: "{scene["envmap"]}_lumis.exr")],')
    lines.append(")")
    path = work / f"{scene['name']}.ron"
    path.write_text("\n".join(lines) + "\n")
    return path


def mitsuba_dict(scene, work, emitter_samples=1, bsdf_samples=1):
    import mitsuba as mi
    c = scene["camera"]
    d = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": emitter_samples,
                       "bsdf_samples": bsdf_samples},
        "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": c["fov"],
            "to_world": mi.ScalarTransform4f(look_at(c["origin"], c["target"], c["up"]).tolist()),
            "film": {"type": "hdrfilm", "width": scene["size"][0], "height": scene["size"][1],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": scene["spp"]},
        },
    }
    for name, (kind, value) in scene["bsdfs"].items():
        inner = ({"type": "diffuse", "reflectance": {"type": "rgb", "value": list(value)}}
                 if kind == "diffuse" else
                 {"type": "roughconductor", "distribution": "ggx", "alpha": value,
                  "material": "none"})
        d[f"bsdf_{name}"] = {"type": "twosided", "id": name, "bsdf": inner}
    for i, s in enumerate(scene["shapes"]):
        shape = {"bsdf": {"type": "ref", "id": s["bsdf"]}}
        if s["shape"] == "sphere":
            shape.update(type="sphere", center=list(s["center"]), radius=s["radius"])
        elif s["shape"] == "mesh":
            shape.update(type="ply", filename=str(work / f"{s['file']}.ply"), face_normals=True)
        else:
            shape.update(type=s["shape"], to_world=mi.ScalarTransform4f(s["matrix"].tolist()))
        if "radiance" in s:
            shape["emitter"] = {"type": "area",
                                "radiance": {"type": "rgb", "value": list(s["radiance"])}}
        d[f"shape_{i}"] = shape
    if "envmap" in scene:
        d["envmap"] = {"type": "envmap", "filename": str(work / f"{scene['envmap']}_mitsuba.exr")}
    return d


# ---------------------------------------------------------------------------------------------
# Mitsuba workers: one process per variant keeps its scenes loaded (and its kernels compiled)
# between renders, so that timings exclude loading; lumis is timed by its own summary line.


def worker(variant, work, scene_names):
    import mitsuba as mi
    mi.set_variant(variant)
    import drjit as dr
    scenes = {s["name"]: s for s in all_scenes() if s["name"] in scene_names}
    loaded = {}
    out = sys.stdout
    sys.stdout = sys.stderr  # keep the protocol channel clean
    for line in sys.stdin:
        name, config, seed, path = line.split()
        key = (name, config)
        load_time = 0.0
        if key not in loaded:
            es, bs = (int(x) for x in config.split("/"))
            t = time.perf_counter()
            loaded[key] = mi.load_dict(mitsuba_dict(scenes[name], work, es, bs))
            load_time = time.perf_counter() - t
        t = time.perf_counter()
        image = mi.render(loaded[key], seed=int(seed))
        dr.eval(image)
        dr.sync_thread()
        elapsed = time.perf_counter() - t
        np.save(path, np.array(image))
        out.write(json.dumps({"time": elapsed, "load": load_time}) + "\n")
        out.flush()


class Worker:
    def __init__(self, variant, work, scene_names, env):
        self.variant = variant
        self.proc = subprocess.Popen(
            [sys.executable, __file__, "--worker", variant, "--work", str(work),
             "--scenes", *scene_names],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)

    def render(self, name, config, seed, path):
        self.proc.stdin.write(f"{name} {config} {seed} {path}\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            sys.exit(f"the Mitsuba {self.variant} worker stopped (see its messages above)")
        return json.loads(line), np.load(path)

    def close(self):
        self.proc.stdin.close()
        self.proc.wait()


def lumis_render(binary, ron, seed, exr, threads=2):
    t = time.perf_counter()
    result = subprocess.run(
        [str(binary), "render", str(ron), "--seed", str(seed), "--threads", str(threads),
         "-o", str(exr)], capture_output=True, text=True)
    wall = time.perf_counter() - t
    if result.returncode != 0:
        sys.exit(f"lumis failed on {ron}:\n{result.stderr}")
    # "... loaded in 0.123 s, rendered in 1.234 s, ..."
    summary = result.stderr.strip().splitlines()[-1]
    rendered = float(summary.split("rendered in ")[1].split(" s")[0])
    loaded = float(summary.split("loaded in ")[1].split(" s")[0])
    return {"time": rendered, "load": loaded, "process": wall}, read_exr(exr)


# ---------------------------------------------------------------------------------------------
# The equal-image check.


def compare(runs_a, runs_b, block):
    """Per-channel block means of two renderers' images compared in units of their standard
    error, estimated from the per-pixel spread over independent runs (seeds)."""
    a, b = np.stack(runs_a).astype(np.float64), np.stack(runs_b).astype(np.float64)
    k_a, k_b = len(a), len(b)
    h, w = a.shape[1] // block * block, a.shape[2] // block * block
    a, b = a[:, :h, :w], b[:, :h, :w]
    mean_a, mean_b = a.mean(0), b.mean(0)
    # Variance of each pixel's mean over runs; a block mean's is the sum over its pixels / n².
    var_a, var_b = a.var(0, ddof=1) / k_a, b.var(0, ddof=1) / k_b

    def blocks(x):
        return x.reshape(h // block, block, w // block, block, 3).sum((1, 3))

    n = block * block
    diff = (blocks(mean_a) - blocks(mean_b)) / n
    sigma = np.sqrt(blocks(var_a + var_b)) / n
    flat = (sigma == 0) & (diff == 0)  # black in both, in every run
    z = np.where(flat, 0.0, np.abs(diff) / np.where(sigma > 0, sigma, np.inf))
    z[(sigma == 0) & (diff != 0)] = np.inf
    tested = int((~flat).sum())
    # Two-sided, Bonferroni over the blocks tested: a 1 % chance of any false alarm.
    z_crit = statistics.NormalDist().inv_cdf(1 - 0.01 / (2 * max(tested, 1)))
    g_diff = mean_a.mean((0, 1)) - mean_b.mean((0, 1))
    g_sigma = np.sqrt((var_a.sum((0, 1)) + var_b.sum((0, 1)))) / (h * w)
    g_z = np.abs(g_diff) / np.where(g_sigma > 0, g_sigma, np.inf)
    down = lambda x: x.reshape(h // 8, 8, w // 8, 8, 3).mean((1, 3))
    rel_l1 = np.abs(down(mean_a) - down(mean_b)).sum() / max(np.abs(down(mean_b)).sum(), 1e-30)
    return {
        "blocks": tested, "z_crit": z_crit, "max_z": float(z.max()),
        "mean_z2": float((z[~flat] ** 2).mean()) if tested else 0.0,
        "global_rel": (g_diff / np.maximum(np.abs(mean_b.mean((0, 1))), 1e-30)).tolist(),
        "global_z": g_z.tolist(), "rel_l1": float(rel_l1),
        "ok": bool(z.max() <= z_crit and g_z.max() <= 3.0),
    }


# ---------------------------------------------------------------------------------------------


def all_scenes():
    scenes = [cornell(), veach()]
    if SHARED_DRAGON.exists():
        scenes.insert(1, dragon())
    return scenes


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=REPO / "target" / "race")
    p.add_argument("--scenes", nargs="*", default=None, help="cornell dragon veach (default all)")
    p.add_argument("--check-runs", type=int, default=6, help="seeds per renderer for the check")
    p.add_argument("--timing-runs", type=int, default=5, help="interleaved timed runs")
    p.add_argument("--block", type=int, default=16, help="block edge (pixels) of the check")
    p.add_argument("--no-llvm", action="store_true", help="skip Mitsuba llvm_ad_rgb")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    args = p.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    if args.worker:
        return worker(args.worker, args.work, args.scenes)

    if not SHARED_DRAGON.exists():
        print(f"skipping the dragon scene: {SHARED_DRAGON} not found")
    scenes = [s for s in all_scenes() if args.scenes is None or s["name"] in args.scenes]
    prepare_assets(args.work, scenes)
    print(f"Veach glossy masking: height-correlated vs separable Smith differ by at most "
          f"{glossy_masking_difference():.1e} (relative) at the plates' centres")
    variants = ["scalar_rgb"] + ([] if args.no_llvm else ["llvm_ad_rgb"])
    names = [s["name"] for s in scenes]
    workers = {v: Worker(v, args.work, names, os.environ.copy()) for v in variants}
    ok_all, table = True, []
    try:
        for scene in scenes:
            name = scene["name"]
            ron = write_lumis_scene(scene, args.work)
            exr = args.work / f"{name}_lumis.exr"
            configs = ["1/1"] + (["4/4"] if name == "veach" else [])
            # 1. Equal images first: independent seeds of each renderer at the race's spp.
            runs = {"lumis": [lumis_render(args.lumis, ron, s, exr)[1]
                              for s in range(args.check_runs)]}
            first = {}
            for v, wk in workers.items():
                runs[v] = []
                for config in reversed(configs):  # "1/1" last: its images are compared
                    for s in range(args.check_runs if config == "1/1" else 1):
                        t, image = wk.render(name, config, 1000 + s,
                                             args.work / f"{name}_{v}.npy")
                        if s == 0:
                            # The first render of a scene includes loading and, for llvm,
                            # tracing and compiling its kernels.
                            first[f"{v} {config}"] = (t["load"], t["time"])
                        if config == "1/1":
                            runs[v].append(image)
            for v in variants:
                c = compare(runs["lumis"], runs[v], args.block)
                ok_all &= c["ok"]
                print(f"{name}: lumis vs Mitsuba {v} direct 1/1, {args.check_runs} seeds each, "
                      f"{c['blocks']} {args.block}x{args.block}-pixel blocks x channels: "
                      f"max |z| {c['max_z']:.2f} (tolerance {c['z_crit']:.2f}), mean z² "
                      f"{c['mean_z2']:.2f}, global mean rel. diff "
                      f"{', '.join(f'{x:+.2e}' for x in c['global_rel'])} (|z| "
                      f"{', '.join(f'{x:.2f}' for x in c['global_z'])}, tolerance 3), "
                      f"rel. L1 of 8x8-downsampled means {c['rel_l1']:.3%}: "
                      f"{'AGREE' if c['ok'] else 'DISAGREE'}")
            # 2. Then times: interleaved rounds, one run of each contender per round.
            times = {}
            for r in range(args.timing_runs):
                t, _ = lumis_render(args.lumis, ron, 100 + r, exr)
                times.setdefault("lumis", []).append(t)
                for v, wk in workers.items():
                    for config in configs:
                        t, _ = wk.render(name, config, 2000 + r,
                                         args.work / f"{name}_{v}.npy")
                        times.setdefault(f"{v} {config}", []).append(t)
            med = {k: statistics.median(x["time"] for x in v) for k, v in times.items()}
            proc = statistics.median(x["process"] for x in times["lumis"])
            lumis_times = [x["time"] for x in times["lumis"]]
            for k in med:
                extra = (f"{proc:8.3f} (whole process)" if k == "lumis" else
                         f"{first[k][0]:.3f} load + {first[k][1]:.3f} first render")
                ratio = ratio_interval([x["time"] for x in times[k]], lumis_times)
                table.append((name, k, med[k], fmt_ratio(*ratio), extra))
    finally:
        for wk in workers.values():
            wk.close()

    print()
    print(f"Median render time over {args.timing_runs} interleaved runs, loading and JIT "
          f"compilation excluded; ratio = time / lumis time, the geometric mean of the rounds' "
          f"ratios with its 95 % confidence interval. 'With loading': lumis's whole "
          f"process (parse, glTF, BVH, render, EXR and PNG written); Mitsuba's scene loading "
          f"and first render (llvm: with tracing and kernel compilation).")
    print(f"{'scene':8} {'renderer (Mitsuba direct: emitter/bsdf samples)':40} {'time s':>8} "
          f"{'ratio [95 % CI]':>23}  with loading, s")
    for name, k, t, ratio, extra in table:
        label = "lumis power, samples 2" if k == "lumis" else f"Mitsuba {k}"
        print(f"{name:8} {label:40} {t:8.3f} {ratio:>23}  {extra}")
    if not ok_all:
        print("\nSome images DISAGREE: the timings above compare different images.")
        sys.exit(1)


if __name__ == "__main__":
    main()
