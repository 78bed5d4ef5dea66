"""Every paper package keeps the observer contract of :mod:`observers._common`."""
from __future__ import annotations

import dataclasses
import importlib
import inspect
import pathlib

import numpy as np
import pytest

from observers._common import CONTRACT, Errors, Figure, contract_problems
from observers.claims import PAPER_MODULES

PACKAGES = sorted(PAPER_MODULES)
ROOT = pathlib.Path(__file__).resolve().parents[2] / "observers"


@pytest.mark.parametrize("name", PACKAGES)
def test_package_keeps_the_contract(name):
    mod = importlib.import_module(f"observers.{name}")
    assert contract_problems(mod) == []


@pytest.mark.parametrize("name", PACKAGES)
def test_dataclasses_are_frozen(name):
    """One dataclass style: every dataclass of a paper package is frozen."""
    for sub in ("design", "systems", "example", "figures", "claims", "falsification"):
        mod = importlib.import_module(f"observers.{name}.{sub}")
        for obj in vars(mod).values():
            if (inspect.isclass(obj) and obj.__module__ == mod.__name__
                    and dataclasses.is_dataclass(obj)):
                assert obj.__dataclass_params__.frozen, f"{mod.__name__}.{obj.__name__}"


@pytest.mark.parametrize("path", sorted(ROOT.rglob("*.py")), ids=lambda p: p.name
                         if p.parent == ROOT else f"{p.parent.name}/{p.name}")
def test_library_code_neither_prints_nor_picks_a_backend(path):
    """Messages go through logging (the main job shows them); the backend is the user's."""
    if path.name in ("reproduce.py", "__main__.py"):
        return                                      # the command line itself
    import ast
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            assert not (isinstance(f, ast.Name) and f.id == "print"), \
                f"{path}:{node.lineno} prints"
            assert not (isinstance(f, ast.Attribute) and f.attr == "use"
                        and isinstance(f.value, ast.Name) and f.value.id == "matplotlib"), \
                f"{path}:{node.lineno} chooses a matplotlib backend"


@pytest.mark.parametrize("name", PACKAGES)
def test_figures_are_saved_through_save_figure(name):
    src = (ROOT / name / "figures.py").read_text()
    assert ".savefig(" not in src, "write figures with observers._common.save_figure"


def test_contract_problems_names_what_is_missing():
    import types
    fake = types.ModuleType("observers.fake")
    fake.__all__ = ["simulate"]

    def simulate(dsg, x0, *, t_max):
        return None
    fake.simulate = simulate
    problems = "\n".join(contract_problems(fake))
    for key in CONTRACT:
        if key != "simulate":
            assert f"lacks {key!r}" in problems
    assert "positional parameters must start ['observer', 'x0', 'xhat0']" in problems
    assert "keyword-only parameter 'noise' missing" in problems
    assert "**simulate_kwargs" in problems


def test_errors_mapping():
    E = Errors(np.arange(3.0), [0, 0, 1], e=np.ones(3), xbar=np.zeros((3, 2)))
    assert E.e.shape == (3, 1) and set(E) == {"e", "xbar"} and E["xbar"].shape == (3, 2)
    assert np.allclose(E.norm("xbar"), 0.0) and np.allclose(E.norm(), 1.0)
    with pytest.raises(ValueError, match="'xbar' must have 3 rows"):
        Errors(np.arange(3.0), [0, 0, 1], e=np.ones(3), xbar=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="t and j"):
        Errors(np.arange(3.0), [0, 0], e=np.ones(3))
    with pytest.raises(TypeError):
        E["e"] = 0                                   # read-only


def test_figure_renders_data_then_drawing(tmp_path):
    from matplotlib.figure import Figure as MplFigure
    calls = []

    def data():
        calls.append("data")
        return np.linspace(0, 1, 5)

    def draw(x):
        fig = MplFigure()
        fig.add_subplot().plot(x, x ** 2, label="x^2")
        return fig

    f = Figure("demo", "a demo", data, draw, lambda x: f"{x.size} points")
    path = f.render(tmp_path)
    assert path.name == "demo.png" and path.with_suffix(".txt").read_text() == "5 points\n"
    assert calls == ["data"]


@pytest.mark.parametrize("name", PACKAGES)
def test_the_package_all_is_a_small_public_surface(name):
    """``__all__`` is the contract's names and the paper's observer and design;
    every other name of the files is imported from its file (and stays an
    attribute of the package)."""
    import types

    from observers._common import PUBLIC_MAX
    pkg = importlib.import_module(f"observers.{name}")
    assert set(CONTRACT) <= set(pkg.__all__) and len(pkg.__all__) <= PUBLIC_MAX
    design = importlib.import_module(f"observers.{name}.design")
    private = [k for k in design.__all__ if k not in pkg.__all__]
    assert private and all(getattr(pkg, k) is getattr(design, k) for k in private)
    fake = types.ModuleType(pkg.__name__)
    vars(fake).update({k: v for k, v in vars(pkg).items() if k != "__all__"})
    fake.__all__ = [*pkg.__all__, *private, "nowhere"]
    fake.nowhere = object()
    problems = "\n".join(contract_problems(fake))
    assert f"has {len(fake.__all__)} names: at most {PUBLIC_MAX}" in problems
    assert "lists 'nowhere', which no file of the package exports" in problems
    fake.__all__ = [k for k in pkg.__all__ if not inspect.isclass(getattr(pkg, k))]
    assert "names no observer" in "\n".join(contract_problems(fake))
