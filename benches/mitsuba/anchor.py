#!/usr/bin/env python3
"""Where the render time goes: Mitsuba 3's llvm_ad_rgb against lumis on the race scenes.

For each scene, renders it with Mitsuba (its kernels compiled by a warm-up render first) and with
lumis, one thread each, under `perf record` (sampling, enabled only around the timed renders),
and splits the samples into ray traversal (Embree and its shape callbacks; lumis' BVH and
intersection routines) and everything else (Mitsuba's JIT-compiled megakernel; lumis' sampling,
shading, weighting and glue). Prints CPU seconds per render (median of interleaved rounds, from
the processes' own CPU clocks), the split in seconds, and lumis' time over Mitsuba's for the
whole, the traversal and the rest with 95 % intervals, so that a design aims at the part that
matters (docs/performance.md, "Where the time goes"). Run through anchor.sh.
"""

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import race  # noqa: E402
from ab import fmt_ratio, ratio_interval  # noqa: E402

# lumis' routines that trace rays (the rest of its time is sampling, shading and glue).
LUMIS_TRAVERSAL = re.compile(
    r"bvh::traverse|Geometry::(intersect|first_hits|may_meet)|ray_meets_triangle|sphere_roots"
    r"|ShadingPoint::sees|trace_together|reaches_light")
# lumis' loading (decoding, BVH build): left out of its split and of its time.
LUMIS_LOADING = re.compile(r"exr::|gltf|png::|zune|bvh::build|obvhs|inflate|miniz")
# Mitsuba's libraries that trace rays: Embree and the shapes' intersection callbacks.
MITSUBA_TRAVERSAL = re.compile(r"^libembree|^(sphere|disk|cylinder)\.so$")


def mitsuba_worker(args):
    """Loads one scene, renders it once to compile its kernels, then renders it `runs` times
    with perf's events enabled through its control fifo; prints CPU seconds per render."""
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    import drjit as dr
    scene = next(s for s in race.all_scenes() if s["name"] == args.worker)
    loaded = mi.load_dict(race.mitsuba_dict(scene, args.work, args.per_light, args.per_light))
    # One thread after loading: loading the dragon on a one-thread pool does not finish.
    dr.set_thread_count(1)
    image = mi.render(loaded, seed=0)
    dr.eval(image)
    dr.sync_thread()
    with open(args.control, "w") as ctl:
        ctl.write("enable\n")
    cpu = []
    for seed in range(1, args.runs + 1):
        t = time.process_time()
        image = mi.render(loaded, seed=seed)
        dr.eval(image)
        dr.sync_thread()
        cpu.append(time.process_time() - t)
    with open(args.control, "w") as ctl:
        ctl.write("disable\n")
    print(json.dumps(cpu))


def perf_split(data, traversal, key, loading=None):
    """Fractions of perf samples in traversal and in loading, from `perf report` sorted by
    `key`; the traversal fraction is of the samples outside loading."""
    out = subprocess.run(["perf", "report", "-i", str(data), "--sort", key, "--stdio"],
                         capture_output=True, text=True, check=True).stdout
    total = inside = loads = 0.0
    for line in out.splitlines():
        m = re.match(r"\s*([\d.]+)%\s+(.*)$", line)
        if not m:
            continue
        share, name = float(m.group(1)), m.group(2).strip()
        name = re.sub(r"^\[\.\]\s*", "", name)
        total += share
        if loading and loading.search(name):
            loads += share
        elif traversal.search(name):
            inside += share
    if total - loads <= 0:
        return float("nan"), 0.0
    return inside / (total - loads), loads / total


def mitsuba_round(args, tmp, name, per_light):
    """One Mitsuba process: loads, warms up, renders once under perf; (CPU s, traversal share).
    Its CPU time is its own clock's (perf's process is not counted)."""
    fifo, data = tmp / "ctl", tmp / "mitsuba.data"
    os.mkfifo(fifo)
    worker = subprocess.run(
        ["perf", "record", "-q", "-F", "1999", "-D", "-1", "--control", f"fifo:{fifo}",
         "-o", str(data), sys.executable, __file__, "--worker", name, "--work", str(args.work),
         "--control", str(fifo), "--runs", "1", "--per-light", str(per_light)],
        capture_output=True, text=True)
    os.unlink(fifo)
    if worker.returncode != 0:
        sys.exit(f"the Mitsuba worker failed on {name}:\n{worker.stderr}")
    (cpu,) = json.loads(worker.stdout.strip().splitlines()[-1])
    share, _ = perf_split(data, MITSUBA_TRAVERSAL, "dso")
    return cpu, share


def lumis_cpu(binary, ron, exr, record=None):
    """lumis' CPU seconds for one render, or its perf profile in `record` (perf's own CPU time
    would count as lumis', so a profiled run is not timed)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    cmd = [str(binary), "render", str(ron), "--threads", "1", "--output", str(exr)]
    if record:
        cmd = ["perf", "record", "-q", "-F", "1999", "-o", str(record)] + cmd
    subprocess.run(cmd, check=True, capture_output=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=race.REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=race.REPO / "target" / "race")
    p.add_argument("--scenes", nargs="*", default=None, help="cornell dragon veach (default all)")
    p.add_argument("--runs", type=int, default=5, help="interleaved rounds per scene")
    p.add_argument("--worker", help=argparse.SUPPRESS)
    p.add_argument("--control", help=argparse.SUPPRESS)
    p.add_argument("--per-light", type=int, default=1, help=argparse.SUPPRESS)
    args = p.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    if args.worker:
        return mitsuba_worker(args)

    scenes = [s for s in race.all_scenes() if args.scenes is None or s["name"] in args.scenes]
    race.prepare_assets(args.work, scenes)
    print(f"{'scene':<8} {'renderer':<24} {'CPU s/render':>12} {'traversal':>10} "
          f"{'s traversal':>12} {'s the rest':>11}")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scene in scenes:
            name = scene["name"]
            ron = race.write_lumis_scene(scene, args.work)
            # lumis samples every light per camera sample; Mitsuba's `direct` one per emitter
            # sample: Veach's four lights are compared at 4/4 as in the race.
            per_light = 4 if name == "veach" else 1
            # Interleaved rounds, each renderer profiled in each: (CPU s, traversal share).
            rounds = {"mitsuba": [], "lumis": []}
            for _ in range(args.runs):
                rounds["mitsuba"].append(mitsuba_round(args, tmp, name, per_light))
                data = tmp / "lumis.data"
                cpu = lumis_cpu(args.lumis, ron, tmp / f"{name}.exr")
                lumis_cpu(args.lumis, ron, tmp / f"{name}.exr", data)
                share, loading = perf_split(data, LUMIS_TRAVERSAL, "symbol", LUMIS_LOADING)
                rounds["lumis"].append((cpu * (1 - loading), share))
            for label, key in ((f"Mitsuba llvm_ad_rgb {per_light}/{per_light}", "mitsuba"),
                               ("lumis", "lumis")):
                cpu = [c for c, _ in rounds[key]]
                share = statistics.median(f for _, f in rounds[key])
                t = statistics.median(cpu)
                print(f"{name:<8} {label:<24} {t:>12.3f} {share:>9.1%} {share * t:>12.3f} "
                      f"{(1 - share) * t:>11.3f}")
            parts = {k: ([c for c, _ in v], [c * f for c, f in v], [c * (1 - f) for c, f in v])
                     for k, v in rounds.items()}
            ratios = [fmt_ratio(*ratio_interval(a, b))
                      for a, b in zip(parts["lumis"], parts["mitsuba"])]
            print(f"{name:<8} lumis / Mitsuba, 95 % intervals over {args.runs} rounds: "
                  f"all {ratios[0]}, traversal {ratios[1]}, the rest {ratios[2]}")
    print("machine:", race_machine())


def race_machine():
    model = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
    m = re.search(r"Model name:\s*(.*)", model)
    flags = open("/proc/cpuinfo").read()
    return (f"{os.cpu_count()} cores, {m.group(1) if m else 'unknown CPU'}, "
            f"{'AVX-512' if 'avx512f' in flags else 'no AVX-512'}, "
            f"load average {' '.join(open('/proc/loadavg').read().split()[:3])}")


if __name__ == "__main__":
    main()
