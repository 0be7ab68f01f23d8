"""Renders in passes through the binding: the CLI's image and error, the callback that stops."""

import numpy as np
import pytest

import lumis
from conftest import SCENES, run_cli

OVERRIDES = ["film.width=32", "film.height=24", "integrator.samples=4"]


def test_a_render_to_a_target_is_the_clis_and_states_its_error(cli, tmp_path):
    path = str(SCENES / "veach.ron")
    args = ["render", path, "--quiet", "--target-error", "0.05", "--max-spp", "64"]
    for o in OVERRIDES:
        args += ["--set", o]
    out = run_cli(cli, *args, "-o", str(tmp_path / "cli.exr"), cwd=tmp_path)
    assert out.returncode == 0, out.stderr

    seen = []
    result = lumis.load(path, overrides=OVERRIDES).render(
        target_error=0.05, max_spp=64, on_pass=seen.append
    )
    result.write(tmp_path / "py.exr")
    # The same passes, hence the same image: the previews (which hold no timings) are equal.
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    assert [p.index for p in seen] == list(range(len(seen)))
    assert [p.samples for p in result.passes] == [p.samples for p in seen]
    assert seen[-1].last and not any(p.last for p in seen[:-1])
    low, high = result.error_interval
    assert 0 <= low <= result.error <= high
    assert result.stopped in ("target", "max-spp")
    assert not result.partial


def test_on_pass_returning_false_stops_a_render_marked_partial():
    scene = lumis.load(str(SCENES / "veach.ron"), overrides=OVERRIDES)
    result = scene.render(target_error=0.0, max_spp=256, on_pass=lambda p: p.index < 1)
    assert len(result.passes) == 2
    assert result.partial
    assert np.isfinite(result["color"]).all()


def test_bad_settings_are_refused():
    scene = lumis.load(str(SCENES / "veach.ron"), overrides=OVERRIDES)
    with pytest.raises(ValueError, match="target_error"):
        scene.render(target_error=-1.0)
    with pytest.raises(ValueError):
        scene.render(target_error=0.1, spp=4)


def test_per_pixel_budgets_give_the_clis_image_and_need_passes(cli, tmp_path):
    path = str(SCENES / "veach.ron")
    args = ["render", path, "--quiet", "--spp", "16", "--passes", "4", "--budgets", "per-pixel"]
    for o in OVERRIDES:
        args += ["--set", o]
    out = run_cli(cli, *args, "-o", str(tmp_path / "cli.exr"), cwd=tmp_path)
    assert out.returncode == 0, out.stderr

    scene = lumis.load(path, overrides=OVERRIDES)
    result = scene.render(spp=16, passes=4, budgets="per-pixel")
    result.write(tmp_path / "py.exr")
    assert (tmp_path / "py.png").read_bytes() == (tmp_path / "cli.png").read_bytes()
    assert np.isfinite(result["color"]).all()
    # Per-pixel budgets spread the same samples differently from uniform passes.
    uniform = scene.render(spp=16, passes=4)
    assert not np.array_equal(uniform["color"], result["color"])
    with pytest.raises(ValueError, match="per-pixel"):
        scene.render(spp=16, budgets="per-pixel")
    with pytest.raises(ValueError):
        scene.render(spp=16, passes=4, budgets="sideways")
