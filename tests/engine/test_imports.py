"""The engine's house, checked from its imports.

Every import statement of every module of ``hybridsim`` (function-level ones
included) is read with :mod:`ast`; the graph of modules they form must have
no circle (no strongly connected component of more than one module), the
paths (the Python loop, the vectorized batch, the compiled kernels) must
never reach the front door (:mod:`hybridsim.run`), and no module may import
one of a level above its own. The package and its compiled path must import
without numba.
"""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import networkx as nx
import pytest

PKG = Path(__file__).resolve().parents[2] / "hybridsim"

#: the house's levels, top first (HOUSE.md): a module imports only its own
#: level and those below it
LEVELS = (
    ("capabilities", {"explore", "falsification", "sensitivity", "testing", "plot", "stl",
                      "estimate", "arch", "_stl_eval", "_stl_signal", "_stl_window_nb",
                      "_explore_tree", "_estimate_runs", "_sensitivity_maps", "_falsify_space",
                      "_falsify_search", "_estimate_stats", "_plot_sample"}),
    ("front door", {"run", "batch", "_batch_reduce", "_batch_attributes"}),
    ("paths", {"solve", "batch_vectorized", "compiled",
               "_sde", "_random_jumps", "_variational", "_solve_state", "_solve_solver",
               "_batch_maps", "_batch_samples", "_batch_steps", "_batch_events",
               "_batch_watch"}),
    ("shared and data", {"rules", "options", "events", "_rk", "_progress", "_version", "_interrupt",
                         "system", "compose", "_compose_network", "history", "arc",
                         "_arc_access", "_arc_checks", "_arc_io", "_arc_records",
                         "_compose_checks", "arc_batch", "library",
                         "_source", "_source_read", "_source_guards", "_source_last_axis",
                         "_source_rewrite", "_source_shapes", "_source_slots", "_source_unroll",
                         "brownian"}),
)


def _modules():
    """``{dotted name: path}`` of every module of the package."""
    out = {}
    for path in sorted(PKG.rglob("*.py")):
        rel = path.relative_to(PKG.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _targets(name, path, node, modules):
    """The package's modules that the import ``node`` in module ``name`` runs."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    if isinstance(node, ast.Import):
        bases = [a.name for a in node.names]
        found = []
        for b in bases:
            found += [m for m in modules if b == m or b.startswith(m + ".")][-1:]
        return [b for b in bases if b in modules] or found
    if node.level:
        base = package.split(".")
        base = base[:len(base) - node.level + 1]
        mod = ".".join(base + ([node.module] if node.module else []))
    else:
        mod = node.module or ""
    subs = [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in modules]
    # ``from .. import rules``: the submodule (its package is being imported already);
    # ``from . import CompiledSystem``: the package's own module
    whole = mod in modules and len(subs) < len(node.names)
    return subs + ([mod] if whole else [])


def _graph():
    modules = _modules()
    g = nx.DiGraph()
    g.add_nodes_from(modules)
    where = {}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for t in _targets(name, path, node, modules):
                    if t != name:
                        g.add_edge(name, t)
                        where.setdefault((name, t), f"{path.name}:{node.lineno}")
    return g, where


def _level(name):
    parts = name.split(".")
    if len(parts) == 1:
        return None                     # the package's face: imports everything
    for i, (_, members) in enumerate(LEVELS):
        if parts[1] in members:
            return i
    raise AssertionError(f"{name}: a module of no level of the house (add it to LEVELS)")


def test_the_imports_form_no_circle():
    g, where = _graph()
    assert len(g) > 20 and g.number_of_edges() > 40         # the parse found the package
    big = [sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1]
    detail = [[where[e] for e in g.subgraph(c).edges] for c in big]
    assert not big, f"import circles: {big} (at {detail})"


def test_the_paths_never_reach_the_front_door():
    g, _ = _graph()
    paths = [m for m in g if m.split(".")[1:2] and m.split(".")[1] in
             ("solve", "batch_vectorized", "compiled")]
    assert "hybridsim.solve" in paths and "hybridsim.compiled._kernel" in paths
    for m in paths:
        below = nx.descendants(g, m)
        assert "hybridsim.run" not in below and "hybridsim.batch" not in below, m


def test_no_import_runs_back_up():
    g, where = _graph()
    up = [(a, b, where[a, b]) for a, b in g.edges
          if _level(a) is not None and _level(b) is not None and _level(b) < _level(a)]
    assert not up, f"imports of a level above: {up}"


_NO_NUMBA = """
import sys
sys.modules["numba"] = None          # import numba raises ImportError
import hybridsim, hybridsim.compiled
assert not hybridsim.compiled.available()
import numpy as np
arc = hybridsim.simulate(hybridsim.HybridSystem.from_functions(
    flow_map=lambda x: -x, state_dim=1), [1.0], t_max=1.0, backend="auto")
assert arc.termination.name == "T_MAX"
try:
    hybridsim.compiled.compile_kernels()
except ImportError as e:
    assert "numba" in str(e)
else:
    raise AssertionError("compiled without numba")
print("ok")
"""


@pytest.mark.parametrize("numba", [False, True], ids=["without numba", "with numba"])
def test_the_package_and_its_compiled_path_import(numba):
    code = _NO_NUMBA if not numba else "import hybridsim, hybridsim.compiled; print('ok')"
    out = subprocess.run([sys.executable, "-c", code], cwd=PKG.parent, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
