"""The example of docs/examples runs and writes its figure."""

import subprocess
import sys

import matplotlib.image
import numpy as np

from conftest import REPO

SCRIPT = REPO / "docs" / "examples" / "veach_alpha.py"


def test_example_script_writes_its_figure(tmp_path):
    out = subprocess.run(
        [sys.executable, str(SCRIPT), str(tmp_path / "figures"), "--width", "64", "--spp", "1", "--samples", "8"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert out.returncode == 0, out.stderr
    figure = tmp_path / "figures" / "veach_alpha.png"
    assert out.stdout.strip().splitlines()[-1] == str(figure)
    assert "variance ratio alpha / balance" in out.stdout
    pixels = matplotlib.image.imread(figure)
    assert pixels.shape == (800, 1000, 4)
    # Four panels with content: far from a blank page.
    assert pixels[..., :3].std() > 0.1
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == ["veach_alpha.png"]


NOTEBOOK = REPO / "docs" / "examples" / "veach_alpha.ipynb"


def test_notebook_cells_run(tmp_path, monkeypatch):
    import json

    import matplotlib

    matplotlib.use("Agg")
    cells = json.loads(NOTEBOOK.read_text())["cells"]
    source = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "code")
    full_size = "WIDTH, SPP, SAMPLES = 320, 4, 64"
    assert full_size in source
    source = source.replace(full_size, "WIDTH, SPP, SAMPLES = 64, 1, 8")
    # The notebook runs from its directory; its temporary output goes under tmp_path.
    monkeypatch.chdir(NOTEBOOK.parent)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)
    namespace = {}
    exec(compile(source, str(NOTEBOOK), "exec"), namespace)
    assert namespace["alpha"]["alpha_color"].shape == (48, 64, 3)
    assert np.isfinite(namespace["ratio"]).any()
    assert len(list(tmp_path.rglob("veach.exr"))) == 1
