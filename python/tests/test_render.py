"""Renders through the binding: the CLI's files bit for bit, dict and RON forms, layers, plugins."""

import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import lumis
from conftest import SCENES, run_cli

# Small versions of the repository's scenes (64 × 48 pixels), as `--set` overrides.
SMALL = {
    "cornell": ["film.width=48", "film.height=48", "integrator.samples=4"],
    "veach": ["film.width=64", "film.height=48", "integrator.samples=8"],
}


@pytest.mark.parametrize(
    "scene, integrator, extra",
    [
        ("cornell", None, []),
        ("veach", "alpha", ['integrator.aovs=["alpha", "sampling_variance", "samples"]']),
    ],
)
def test_written_files_are_the_clis_bit_for_bit(cli, tmp_path, scene, integrator, extra):
    path = str(SCENES / f"{scene}.ron")
    overrides = SMALL[scene] + extra
    args = ["render", path, "--quiet", "--spp", "2", "--seed", "7", "-o", str(tmp_path / "cli.exr")]
    for o in overrides + ([f"integrator.type={integrator}"] if integrator else []):
        args += ["--set", o]
    out = run_cli(cli, *args, cwd=tmp_path)
    assert out.returncode == 0, out.stderr

    result = lumis.load(path, overrides=overrides).render(integrator=integrator, spp=2, seed=7)
    written = result.write(tmp_path / "py.exr")

    cli_files = sorted(p.name for p in tmp_path.glob("cli.*"))
    previews = [f"cli.alpha_color{light}.png" for light in ["", "_light0", "_light1", "_light2", "_light3"]]
    assert [Path(w).name.replace("py.", "cli.", 1) for w in written] == [
        "cli.exr",
        "cli.png",
        *(previews if integrator == "alpha" else []),
    ]
    assert sorted(Path(w).name.replace("py.", "cli.", 1) for w in written) == cli_files
    for name in cli_files:
        cli_bytes = (tmp_path / name).read_bytes()
        py_bytes = (tmp_path / name.replace("cli.", "py.", 1)).read_bytes()
        assert cli_bytes == py_bytes, f"{name} differs from the CLI's"


# The α layers of the Veach layout's four lights.
ALPHA_LAYERS = ["alpha", "alpha_color", *(f"alpha_color_light{j}" for j in range(4))]

VEACH_DICT = {
    "camera": {"position": (0, 2, 15), "target": (0, -1.5, 2.5), "fov": 28},
    "film": {"width": 64, "height": 48},
    "sampler": {"spp": 1, "seed": 0},
    "integrator": {"type": "balance", "samples": 8, "aovs": ["alpha"]},
    "bsdfs": {
        "plate0": {"type": "glossy", "roughness": 0.005, "specular": 0.8, "diffuse": 0.05},
        "plate1": {"type": "glossy", "roughness": 0.02, "specular": 0.8, "diffuse": 0.05},
        "plate2": {"type": "glossy", "roughness": 0.05, "specular": 0.8, "diffuse": 0.05},
        "plate3": {"type": "glossy", "roughness": 0.1, "specular": 0.8, "diffuse": 0.05},
        "floor": {"type": "diffuse", "reflectance": 0.2},
        "black": {"type": "diffuse", "reflectance": 0},
    },
    "shapes": [
        *(
            {
                "type": "rectangle",
                "bsdf": f"plate{i}",
                "transform": {
                    "scale": (4, 0.55, 1),
                    "look_at": {"origin": origin, "target": target, "up": (0, 0, -1)},
                },
            }
            for i, (origin, target) in enumerate(
                [
                    ((0, -1.2, 1.5), (0, -0.305, 1.9461)),
                    ((0, -1.65, 2.9), (0, -0.7128, 3.2488)),
                    ((0, -2.1, 4.3), (0, -1.1347, 4.5611)),
                    ((0, -2.55, 5.7), (0, -1.5658, 5.877)),
                ]
            )
        ),
        {
            "type": "rectangle",
            "bsdf": "floor",
            "transform": {
                "scale": (20, 20, 1),
                "rotate": [{"axis": (1, 0, 0), "angle": -90}],
                "translate": (0, -4, 0),
            },
        },
        *(
            {
                "type": "sphere",
                "bsdf": "black",
                "center": (x, 4.5, -1),
                "radius": r,
                "emitter": {"type": "area", "radiance": radiance},
            }
            for x, r, radiance in [
                (3.75, 0.0333, 901.8),
                (1.25, 0.1, 100),
                (-1.25, 0.3, 11.11),
                (-3.75, 0.9, 1.235),
            ]
        ),
    ],
}


def test_dict_and_ron_forms_give_the_same_image():
    ron = lumis.load(
        SCENES / "veach.ron", overrides={"film.width": 64, "film.height": 48, "integrator.samples": 8}
    ).render(integrator="alpha", spp=2, seed=3)
    from_dict = lumis.load_dict(VEACH_DICT).render(integrator="alpha", spp=2, seed=3)
    assert ron.keys() == from_dict.keys() == ["color", *ALPHA_LAYERS]
    for name in ron.keys():
        assert ron[name].shape == from_dict[name].shape
        assert np.array_equal(ron[name], from_dict[name]), name
    assert ron["color"].mean() > 0


def test_dict_scene_resolves_assets_against_base_dir():
    scene = dict(VEACH_DICT, shapes=[{"type": "obj", "bsdf": "floor", "file": "missing.obj"}])
    with pytest.raises(lumis.SceneError, match=r"missing\.obj"):
        lumis.load_dict(scene, base_dir=SCENES)
    with pytest.raises(TypeError, match=r"scene\.bsdfs\.floor\.reflectance.*set"):
        lumis.load_dict(dict(VEACH_DICT, bsdfs={"floor": {"type": "diffuse", "reflectance": {0.2}}}))


def test_layers_by_name_shapes_and_values():
    scene = lumis.load(SCENES / "veach.ron", overrides=SMALL["veach"])
    result = scene.render(
        integrator="alpha", spp=2, aovs=["alpha", "sampling_variance", "samples"], samples=8
    )
    assert result.keys() == ["color", *ALPHA_LAYERS, "sampling_variance", "samples"]
    assert list(result) == result.keys() and len(result) == 9
    assert set(result.layers) == set(result.keys())
    assert result.channels["color"] == ["R", "G", "B"]
    assert result.channels["alpha"] == ["combined", "light0", "light1", "light2", "light3"]
    assert result.channels["samples"] == ["bsdf", "light"]
    assert result.channels["alpha_color_light3"] == ["R", "G", "B"]
    for name, channels in result.channels.items():
        array = result[name]
        assert array.dtype == np.float32
        assert array.shape == (48, 64, len(channels)), name
        assert not array.flags.writeable
        assert np.all(np.isfinite(array)), name
    alpha = result["alpha"]
    assert np.all((alpha >= 0) & (alpha <= 1))
    # A camera sample that finds a surface draws N = 8 samples per light (4 lights), split
    # between the two techniques; one that finds the background draws none.
    counts = result["samples"].sum(axis=2)
    assert np.all(counts % (8 * 4) == 0) and counts.max() == 8 * 4 * 2
    assert result["sampling_variance"].min() >= 0
    assert "alpha" in result and "depth" not in result
    with pytest.raises(KeyError, match="no layer `alpah`.*did you mean `alpha`"):
        result["alpah"]
    assert result.camera_samples == 48 * 64 * 2 and result.pixels == 48 * 64
    assert result.rays > result.camera_samples and result.time > 0
    assert result.spp == 2 and result.seed == 0 and result.integrator["type"] == "alpha"
    assert dict(result.metadata)["integrator"] == "alpha"


def test_renders_are_the_same_for_any_thread_count_and_change_with_the_seed():
    scene = lumis.load(SCENES / "cornell.ron", overrides=SMALL["cornell"])
    one = scene.render(spp=2, threads=1)
    two = scene.render(spp=2, threads=2)
    assert one.threads == 1 and two.threads == 2
    assert np.array_equal(one["color"], two["color"])
    other_seed = scene.render(spp=2, seed=1, threads=2)
    assert not np.array_equal(one["color"], other_seed["color"])


def test_render_parameters_override_and_remove_integrator_parameters():
    scene = lumis.load(SCENES / "veach.ron", overrides=SMALL["veach"])
    assert scene.integrator == {"type": "balance", "samples": 8, "aovs": ["alpha"]}
    plain = scene.render(aovs=None)
    assert plain.keys() == ["color"] and plain.integrator == {"type": "balance", "samples": 8}
    assert scene.render(samples=2).integrator["samples"] == 2


def test_gil_is_released_while_rendering():
    scene = lumis.load(SCENES / "cornell.ron", overrides=SMALL["cornell"])
    done = threading.Event()
    renders = []

    def render():
        renders.append(scene.render(spp=1024, threads=1))
        done.set()

    worker = threading.Thread(target=render)
    worker.start()
    ticks = 0
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    worker.join()
    # The render took long enough for hundreds of ticks of this thread: it ran beside it.
    assert renders[0].time > 0.2, "render too short to tell"
    assert ticks > 50


@pytest.mark.skipif(os.name != "posix", reason="sends SIGINT")
def test_ctrl_c_interrupts_the_render_and_the_scene_renders_again(python_sigint_handler):
    scene = lumis.load(SCENES / "cornell.ron", overrides=SMALL["cornell"])
    # About a minute of work on two cores: only an interrupt ends it within the test.
    timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        scene.render(spp=20000)
    timer.join()
    assert time.monotonic() - start < 30
    assert scene.render(spp=1).camera_samples == 48 * 48


def test_plugins_lists_every_kind_with_parameters():
    plugins = lumis.plugins()
    by_name = {(p["kind"], p["name"]): p for p in plugins}
    for kind, name in [("bsdf", "diffuse"), ("emitter", "area"), ("integrator", "alpha"), ("integrator", "balance")]:
        assert (kind, name) in by_name
    alpha = by_name[("integrator", "alpha")]
    params = {p["name"]: p for p in alpha["parameters"]}
    assert {"samples", "aovs", "mode"} <= set(params)
    assert params["samples"]["type"] == "integer"
    assert all(p["description"] for p in params.values())
