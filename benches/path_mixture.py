#!/usr/bin/env python3
"""`path`'s allocations past the first vertex (`deep_allocation`) against plain `path` (`split`):
the variance of each pixel over independent renders (seeds), averaged over the image, as a ratio
to `split`'s with a 95 % bootstrap interval (renders resampled within each configuration). Two
averages: plain (MSE-like, bright pixels weigh most) and relative (each pixel's variance over its
mean squared).

At equal samples (the default) the figures are variance only: run it anywhere. With --time T
each configuration renders for T seconds (`lumis render --time`), so the ratio is of variance
at equal time: run that only on an idle machine.

    /tmp/pyenv/bin/python benches/path_mixture.py --lumis target/release/lumis
    /tmp/pyenv/bin/python benches/path_mixture.py --lumis target/release/lumis --time 2
"""

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR

REPO = Path(__file__).resolve().parent.parent
SCENES = {
    "cornell": REPO / "scenes" / "cornell.ron",
    "envmap": REPO / "scenes" / "envmap.ron",
}
CONFIGS = {
    "split": [],
    "mixture": ['integrator.deep_allocation="mixture"'],
    "learned": ['integrator.deep_allocation="learned"'],
    "guiding_fraction": ['integrator.deep_allocation="guiding_fraction"'],
}


def read_rgb(path):
    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        if "RGB" in channels:
            return np.asarray(channels["RGB"].pixels, dtype=np.float64)
        return np.stack([np.asarray(channels[c].pixels, dtype=np.float64) for c in "RGB"], -1)


def render(args, scene, config, seed, out):
    sets = [f"film.width={args.width}", f"film.height={args.height}",
            f"sampler.seed={seed}", "integrator.type=path",
            f"integrator.max_depth={args.max_depth}",
            f"integrator.cache_resolution={args.cache_resolution}"
            if config in ("learned", "guiding_fraction") else None,
            *CONFIGS[config]]
    cmd = [str(args.lumis), "render", str(SCENES[scene]), "-q", "-o", str(out)]
    for s in filter(None, sets):
        cmd += ["--set", s]
    if args.time:
        cmd += ["--time", str(args.time), "--max-spp", "65536"]
    else:
        cmd += ["--set", f"sampler.spp={args.spp}", "--passes", str(args.passes)]
    subprocess.run(cmd, check=True)
    return read_rgb(out).mean(-1)


def variances(images):
    """Per-image averages of the pixels' variance over the renders: plain and relative."""
    v = images.var(0, ddof=1)
    m = images.mean(0)
    lit = m > 0
    return v.mean(), (v[lit] / m[lit] ** 2).mean()


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--lumis", type=Path, default=REPO / "target" / "release" / "lumis")
    p.add_argument("--work", type=Path, default=Path("/tmp/path_mixture"))
    p.add_argument("--scenes", default="cornell,envmap")
    p.add_argument("--runs", type=int, default=24)
    p.add_argument("--spp", type=int, default=32)
    p.add_argument("--passes", type=int, default=4)
    p.add_argument("--time", type=float, default=None, help="seconds per render (idle machine)")
    p.add_argument("--width", type=int, default=64)
    p.add_argument("--height", type=int, default=48)
    p.add_argument("--max-depth", type=int, default=5)
    p.add_argument("--cache-resolution", type=int, default=16)
    p.add_argument("--bootstrap", type=int, default=2000)
    args = p.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    for scene in args.scenes.split(","):
        images = {c: np.stack([render(args, scene, c, 1000 + s, args.work / f"{scene}_{c}_{s}.exr")
                               for s in range(args.runs)]) for c in CONFIGS}
        base = images["split"]
        # What learning buys: against the fixed mixture, whose renders share each seed's first
        # pass (α = ½ in both), so the seeds are resampled together.
        for config in ("learned", "guiding_fraction"):
            ratio = np.array(variances(images[config])) / np.array(variances(images["mixture"]))
            boot = []
            for _ in range(args.bootstrap):
                i = rng.integers(0, args.runs, args.runs)
                boot.append(np.array(variances(images[config][i]))
                            / np.array(variances(images["mixture"][i])))
            lo, hi = np.percentile(np.array(boot), [2.5, 97.5], axis=0)
            print(f"{scene}: {config}: variance / mixture's {ratio[0]:.3f} [{lo[0]:.3f}, "
                  f"{hi[0]:.3f}], relative variance / mixture's {ratio[1]:.3f} [{lo[1]:.3f}, "
                  f"{hi[1]:.3f}] (paired seeds)", flush=True)
        for config, imgs in images.items():
            ratio = np.array(variances(imgs)) / np.array(variances(base))
            boot = []
            for _ in range(args.bootstrap):
                a = imgs[rng.integers(0, args.runs, args.runs)]
                b = base[rng.integers(0, args.runs, args.runs)]
                boot.append(np.array(variances(a)) / np.array(variances(b)))
            lo, hi = np.percentile(np.array(boot), [2.5, 97.5], axis=0)
            print(f"{scene}: {config}: variance / split's {ratio[0]:.3f} [{lo[0]:.3f}, {hi[0]:.3f}], "
                  f"relative variance / split's {ratio[1]:.3f} [{lo[1]:.3f}, {hi[1]:.3f}] "
                  f"({args.runs} renders each, "
                  + (f"{args.time} s" if args.time else f"{args.spp} spp in {args.passes} passes")
                  + ")", flush=True)


if __name__ == "__main__":
    sys.exit(main())
