"""Shared fixtures: the repository's scenes and the `lumis` CLI the binding is compared with."""

import json
import os
import signal
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "scenes"

# A small valid scene (tests/common/mod.rs's SMALL_SCENE): a diffuse floor under a square light.
SMALL_SCENE = """Scene(
    camera: (position: (0, 2, -4), target: (0, 0, 0), fov: 40),
    film: (width: 16, height: 16),
    sampler: (spp: 2, seed: 1),
    integrator: (type: "balance", samples: 4),
    bsdfs: {
        "white": (type: "diffuse", reflectance: 0.8),
    },
    shapes: [
        (type: "rectangle", bsdf: "white",
            transform: (scale: (3, 3, 1), rotate: [(axis: (1, 0, 0), angle: -90)])),
        (type: "rectangle", bsdf: "white",
            transform: (scale: (0.5, 0.5, 1), rotate: [(axis: (1, 0, 0), angle: 90)], translate: (0, 2, 0)),
            emitter: (type: "area", radiance: (5, 5, 5))),
    ],
)
"""


@pytest.fixture(scope="session")
def cli() -> Path:
    """The `lumis` CLI: $LUMIS_CLI, or the workspace's binary built with the test profile (which
    `cargo test --workspace` has already built, so this is usually a no-op)."""
    if "LUMIS_CLI" in os.environ:
        return Path(os.environ["LUMIS_CLI"])
    subprocess.run(
        ["cargo", "build", "--locked", "--quiet", "--profile", "test", "--bin", "lumis"],
        cwd=REPO,
        check=True,
    )
    metadata = subprocess.run(
        ["cargo", "metadata", "--format-version", "1", "--no-deps"],
        cwd=REPO,
        check=True,
        capture_output=True,
        text=True,
    )
    target = Path(json.loads(metadata.stdout)["target_directory"])
    return target / "debug" / "lumis"


def run_cli(cli: Path, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(cli), *args], cwd=cwd, capture_output=True, text=True)


@pytest.fixture
def small_scene(tmp_path: Path) -> Path:
    path = tmp_path / "scene.ron"
    path.write_text(SMALL_SCENE)
    return path


@pytest.fixture
def python_sigint_handler():
    """Python's own SIGINT handler for the test's duration: a process started in the background
    without job control (`cmd &` in a script) inherits SIGINT ignored, and Python then never
    raises KeyboardInterrupt, whatever the binding does."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
