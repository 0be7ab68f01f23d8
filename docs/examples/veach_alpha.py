"""The Veach MIS layout rendered with the balance heuristic and with the adaptive α of Lu,
Pacanowski and Granier (2013), side by side: the two images, the α map (red: light sampling,
green: BSDF sampling) and the per-pixel ratio of their sampling variances.

    python docs/examples/veach_alpha.py [OUT_DIR] [--width 320] [--spp 4] [--samples 64]

writes OUT_DIR/veach_alpha.png (default OUT_DIR: a new temporary directory) and prints its path.
The same steps, cell by cell, are in veach_alpha.ipynb.
"""

import argparse
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: no display needed
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import LogNorm

import lumis

SCENE = Path(__file__).resolve().parents[2] / "scenes" / "veach.ron"


def srgb(linear: np.ndarray) -> np.ndarray:
    """Linear RGB to displayable sRGB in [0, 1] (clamped, no tone mapping)."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", type=Path, help="output directory (default: a temporary one)")
    parser.add_argument("--width", type=int, default=320, help="image width (height: 3/4 of it)")
    parser.add_argument("--spp", type=int, default=4, help="camera samples per pixel")
    parser.add_argument("--samples", type=int, default=64, help="N: samples per light per camera sample")
    args = parser.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="lumis-example-"))
    out.mkdir(parents=True, exist_ok=True)

    scene = lumis.load(SCENE, overrides={"film.width": args.width, "film.height": args.width * 3 // 4})
    aovs = ["alpha", "sampling_variance"]
    results = {
        name: scene.render(integrator=name, spp=args.spp, samples=args.samples, aovs=aovs)
        for name in ["balance", "alpha"]
    }
    for name, result in results.items():
        print(f"{name}: {result.time:.2f} s, {result.samples_per_second / 1e6:.3f} M samples/s")

    balance, alpha = results["balance"], results["alpha"]
    # V[L₁] per pixel (luminance, summed over lights): < 1 where the adaptive α has less variance.
    v_balance = balance["sampling_variance"][..., 0]
    v_alpha = alpha["sampling_variance"][..., 0]
    measured = (v_balance > 0) & (v_alpha > 0)
    ratio = np.where(measured, v_alpha / np.where(measured, v_balance, 1.0), np.nan)
    print(
        f"variance ratio alpha / balance over {measured.sum()} pixels: "
        f"median {np.nanmedian(ratio):.3f}, "
        f"{100 * np.nanmean(ratio < 1):.0f} % of pixels below 1"
    )

    fig, axes = plt.subplots(2, 2, figsize=(10, 8), constrained_layout=True)
    axes[0, 0].imshow(srgb(balance["color"]))
    axes[0, 0].set_title(f"balance heuristic (N = {args.samples})")
    axes[0, 1].imshow(srgb(alpha["color"]))
    axes[0, 1].set_title(f"adaptive α (N = {args.samples})")
    axes[1, 0].imshow(alpha["alpha_color"])
    axes[1, 0].set_title("α map (red: light sampling, green: BSDF sampling)")
    finite = ratio[np.isfinite(ratio)]
    span = max(np.percentile(finite, 99), 1 / np.percentile(finite, 1)) if finite.size else 10.0
    image = axes[1, 1].imshow(ratio, cmap="RdBu_r", norm=LogNorm(vmin=1 / span, vmax=span))
    axes[1, 1].set_title("sampling variance, adaptive α / balance")
    fig.colorbar(image, ax=axes[1, 1], shrink=0.8)
    for ax in axes.flat:
        ax.set_xticks([])
        ax.set_yticks([])
    figure = out / "veach_alpha.png"
    fig.savefig(figure, dpi=100)
    print(figure)


if __name__ == "__main__":
    main()
