#!/usr/bin/env python3
"""The race of `path` against Mitsuba 3.9.1's `path` at equal samples: path_check.py's Cornell box
(its blocks, colour bleeding) at `max_depth` 5, converted by `lumis import` (one light per vertex,
power heuristic, as Mitsuba), rendered in interleaved rounds by lumis and by Mitsuba's
`scalar_rgb` and `llvm_ad_rgb` (each Mitsuba variant in its own process, its kernels compiled by a
warm-up render). Prints each renderer's render time (median) and Mitsuba's time over lumis' (> 1:
lumis faster) with 95 % intervals, then checks that the rounds' mean images agree (the race's
block test). Timings mean something only on an idle machine.

Run by hand from the repository (llvm_ad_rgb needs DRJIT_LIBLLVM_PATH, as setup.sh exports):
    benches/mitsuba/.venv/bin/python benches/mitsuba/path_race.py --lumis target/release/lumis
"""

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from race import REPO, compare, lumis_render  # race puts benches/ (ab.py) on the path
from ab import fmt_ratio, ratio_interval  # noqa: E402
from path_check import BLOCKS, BOX  # noqa: E402


def worker(variant, xml, threads):
    """Loads `xml` in `variant`, renders once to compile, then renders one seed per input line
    and answers its render time; the image goes to the path given on the line."""
    import mitsuba as mi
    mi.set_variant(variant)
    import drjit as dr
    scene = mi.load_file(str(xml))
    dr.set_thread_count(threads)
    image = mi.render(scene, seed=0)
    dr.eval(image)
    dr.sync_thread()
    out, sys.stdout = sys.stdout, sys.stderr  # the protocol channel stays clean
    for line in sys.stdin:
        seed, path = line.split()
        t = time.perf_counter()
        image = mi.render(scene, seed=int(seed))
        dr.eval(image)
        dr.sync_thread()
        elapsed = time.perf_counter() - t
        np.save(path, np.array(image))
        out.write(json.dumps(elapsed) + "\n")
        out.flush()


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=REPO / "target" / "path_race")
    p.add_argument("--rounds", type=int, default=5, help="interleaved timed rounds")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--max-depth", type=int, default=5)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--block", type=int, default=16, help="block edge (pixels) of the check")
    p.add_argument("--variants", default="scalar_rgb,llvm_ad_rgb")
    p.add_argument("--worker", nargs=2, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.worker:
        return worker(args.worker[0], args.worker[1], args.threads)

    args.work.mkdir(parents=True, exist_ok=True)
    xml, ron = args.work / "cornell_path.xml", args.work / "cornell_path.ron"
    xml.write_text(BOX.replace("$content", BLOCKS).replace("$max_depth", str(args.max_depth))
                   .replace("$size", str(args.size)).replace("$spp", str(args.spp)))
    imported = subprocess.run([str(args.lumis), "import", str(xml), "-o", str(ron)],
                              capture_output=True, text=True)
    if imported.returncode != 0:
        sys.exit(f"lumis import failed:\n{imported.stderr}")
    variants = args.variants.split(",")
    workers = {v: subprocess.Popen([sys.executable, __file__, "--worker", v, str(xml),
                                    "--threads", str(args.threads)],
                                   stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
               for v in variants}
    # An untimed render first, as each Mitsuba worker's warm-up: the first run pages in the
    # binary and the scene.
    lumis_render(args.lumis, ron, 1999, args.work / "lumis.exr", args.threads)
    times = {name: [] for name in ["lumis"] + variants}
    images = {name: [] for name in times}
    for r in range(args.rounds):
        t, image = lumis_render(args.lumis, ron, 2000 + r, args.work / "lumis.exr",
                                args.threads)
        times["lumis"].append(t["time"])
        images["lumis"].append(image)
        for v, proc in workers.items():
            npy = args.work / f"{v}.npy"
            proc.stdin.write(f"{3000 + r} {npy}\n")
            proc.stdin.flush()
            line = proc.stdout.readline()
            if not line:
                sys.exit(f"the Mitsuba {v} worker stopped (see its messages above)")
            times[v].append(json.loads(line))
            images[v].append(np.load(npy))
    for proc in workers.values():
        proc.stdin.close()
        proc.wait()

    print(f"Cornell box, `path` max_depth {args.max_depth}, {args.size}x{args.size}, "
          f"{args.spp} spp, {args.threads} threads, {args.rounds} interleaved rounds")
    for name, ts in times.items():
        print(f"  {name:<12} render {statistics.median(ts):.3f} s "
              f"({min(ts):.3f}..{max(ts):.3f})")
    ok = True
    for v in variants:
        ratio = fmt_ratio(*ratio_interval(times[v], times["lumis"]))
        c = compare(images["lumis"], images[v], args.block)
        ok &= c["ok"]
        print(f"  Mitsuba {v} / lumis: {ratio} (95 %); images: max |z| {c['max_z']:.2f} "
              f"(tolerance {c['z_crit']:.2f}): {'AGREE' if c['ok'] else 'DISAGREE'}")
    if not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
