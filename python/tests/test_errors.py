"""Errors: Python exceptions of the lumis hierarchy carrying the CLI's messages."""

from pathlib import Path

import pytest

import lumis
from conftest import SMALL_SCENE, run_cli


def cli_message(cli, scene: Path, *extra: str) -> str:
    out = run_cli(cli, "render", str(scene), "--quiet", *extra, cwd=scene.parent)
    assert out.returncode == 1, out.stderr
    assert out.stderr.startswith("error: ")
    return out.stderr[len("error: ") :].strip()


def test_hierarchy():
    for error in [lumis.SceneError, lumis.PluginError, lumis.RenderError, lumis.OutputError]:
        assert issubclass(error, lumis.LumisError)
    assert issubclass(lumis.LumisError, Exception)


def test_syntax_error_has_the_clis_file_line_column_message(cli, tmp_path):
    scene = tmp_path / "broken.ron"
    scene.write_text(SMALL_SCENE.replace("fov: 40)", "fov: 40"))
    with pytest.raises(lumis.SceneError) as caught:
        lumis.load(scene)
    error = caught.value
    assert str(error) == cli_message(cli, scene)
    assert error.file == str(scene)
    assert error.line is not None and error.column is not None
    assert str(error).startswith(f"{scene}:{error.line}:{error.column}: ")
    assert error.message in str(error)


def test_scene_errors_have_the_clis_messages(cli, tmp_path):
    scene = tmp_path / "scene.ron"
    scene.write_text(SMALL_SCENE.replace('"diffuse", reflectance: 0.8', '"difuse", reflectance: 0.8'))
    with pytest.raises(lumis.SceneError, match="did you mean `diffuse`") as caught:
        lumis.load(scene)
    assert str(caught.value) == cli_message(cli, scene)
    assert caught.value.line is None

    with pytest.raises(lumis.SceneError, match="cannot read scene file") as caught:
        lumis.load(tmp_path / "missing.ron")
    assert str(caught.value) == cli_message(cli, tmp_path / "missing.ron")


def test_override_errors_have_the_clis_messages(cli, small_scene):
    with pytest.raises(lumis.SceneError) as caught:
        lumis.load(small_scene, overrides=["film.width=-3"])
    assert str(caught.value) == cli_message(cli, small_scene, "--set", "film.width=-3")
    with pytest.raises(lumis.SceneError, match="index 9 is out of range"):
        lumis.load(small_scene, overrides={"shapes[9].bsdf": "white"})
    with pytest.raises(TypeError, match="not one string"):
        lumis.load(small_scene, overrides="film.width=3")


def test_plugin_errors_have_the_clis_messages(cli, small_scene):
    scene = lumis.load(small_scene)
    with pytest.raises(lumis.PluginError, match="did you mean `balance`") as caught:
        scene.render(integrator="balanse")
    assert str(caught.value) == cli_message(cli, small_scene, "--set", "integrator.type=balanse")
    with pytest.raises(lumis.PluginError, match="unknown parameter `sample`") as caught:
        scene.render(sample=4)
    assert str(caught.value) == cli_message(cli, small_scene, "--set", "integrator.sample=4")
    with pytest.raises(lumis.PluginError, match="samples"):
        scene.render(samples="many")
    with pytest.raises(ValueError, match="spp"):
        scene.render(spp=0)


def test_output_errors(tmp_path, small_scene):
    result = lumis.load(small_scene).render()
    with pytest.raises(lumis.OutputError, match="must end in .exr") as caught:
        result.write(tmp_path / "out.png")
    assert caught.value.path == str(tmp_path / "out.png")
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(lumis.OutputError, match="cannot write"):
        result.write(blocker / "out.exr")
    assert not list(tmp_path.glob("**/.lumis-*.tmp"))
