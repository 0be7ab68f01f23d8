"""The type stub (lumis/_lumis.pyi) describes the module as built: same names, same members."""

import ast
import inspect
from pathlib import Path

import lumis
import lumis._lumis as module

STUB = Path(__file__).resolve().parents[1] / "lumis" / "_lumis.pyi"


def stub_definitions():
    tree = ast.parse(STUB.read_text())
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    classes = {
        n.name: {m.name for m in n.body if isinstance(m, ast.FunctionDef)}
        | {m.target.id for m in n.body if isinstance(m, ast.AnnAssign)}
        for n in tree.body
        if isinstance(n, ast.ClassDef)
    }
    return functions, classes


def test_stub_names_match_the_module():
    functions, classes = stub_definitions()
    public = {name for name in dir(module) if not name.startswith("_")}
    assert public == functions | set(classes)
    # The package adds the study (lumis/_study.py, typed in Python) to the module's names.
    assert set(lumis.__all__) == public | {"Study", "study"}
    for name in functions:
        assert callable(getattr(module, name))
        assert getattr(module, name).__doc__


def test_stub_members_match_the_classes():
    _, classes = stub_definitions()
    for name in ["Scene", "RenderResult", "PassReport"]:
        cls = getattr(module, name)
        runtime = {m for m in dir(cls) if not m.startswith("_") or m in classes[name]}
        stubbed = classes[name]
        assert runtime - {"__new__"} >= stubbed, name
        assert {m for m in runtime if not m.startswith("_")} == {m for m in stubbed if not m.startswith("_")}, name


def test_render_signature_has_keyword_parameters():
    parameters = inspect.signature(lumis.Scene.render).parameters
    assert list(parameters)[1:] == [
        "integrator",
        "spp",
        "seed",
        "threads",
        "target_error",
        "time",
        "passes",
        "metric",
        "confidence",
        "max_spp",
        "max_time",
        "on_pass",
        "budgets",
        "params",
    ]
    assert parameters["params"].kind is inspect.Parameter.VAR_KEYWORD
