"""The package's shape: imports run one way (the import-linter contract in
pyproject.toml), no import cycle, ruff clean, small modules and functions,
every package on disk declared, deprecated modules still working."""

from __future__ import annotations

import ast
import importlib
import importlib.util
import subprocess
import sys
import tomllib
from pathlib import Path

import grimp

ROOT = Path(__file__).parents[1]
PACKAGE = ROOT / "clbeam"
#: the project's style limits (README, Layout): a longer function says why in a comment above it
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 60


def test_import_linter_contract_is_kept():
    r = subprocess.run([str(Path(sys.executable).with_name("lint-imports")), "--no-cache"], cwd=ROOT,
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-2000:]
    assert "1 kept, 0 broken" in r.stdout


def _cycles(graph) -> list:
    """Strongly connected components of more than one module (Tarjan), iteratively."""
    index, low, on_stack, stack, out = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph.modules):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.find_modules_directly_imported_by(root))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            w = next(children, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(graph.find_modules_directly_imported_by(w)))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_no_import_cycle_anywhere():
    graph = grimp.build_graph("clbeam")
    assert _cycles(graph) == []


def test_cycle_finder_finds_a_planted_cycle():
    """The check above can fail: a graph with a -> b -> c -> a has one cycle."""
    g = grimp.ImportGraph()
    for a, b in (("p.a", "p.b"), ("p.b", "p.c"), ("p.c", "p.a"), ("p.c", "p.d")):
        g.add_import(importer=a, imported=b)
    assert _cycles(g) == [["p.a", "p.b", "p.c"]]


def test_ruff_check_passes():
    r = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "."], cwd=ROOT, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stdout[-4000:]


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py"))


def test_no_module_over_800_lines():
    big = {str(p.relative_to(ROOT)): n for p in _modules() if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES}
    assert big == {}


def test_no_function_over_60_lines_without_a_reason():
    long = []
    for p in _modules():
        lines = p.read_text().splitlines()
        for node in ast.walk(ast.parse("\n".join(lines))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                first = (node.decorator_list[0].lineno if node.decorator_list else node.lineno) - 1
                reason = first > 0 and lines[first - 1].lstrip().startswith("#")
                if n > MAX_FUNCTION_LINES and not reason:
                    long.append(f"{p.relative_to(ROOT)}:{node.lineno} {node.name} ({n} lines)")
    assert long == []


def test_every_package_on_disk_is_declared_in_pyproject():
    declared = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    on_disk = {".".join(p.parent.relative_to(ROOT).parts) for p in PACKAGE.rglob("*") if p.is_file()
               and p.suffix in (".py", ".toml") and "__pycache__" not in p.parts}
    assert on_disk - declared == set()
    assert "clbeam.kernels" in declared and (ROOT / "kernels" / "beamform.cl").exists()


def test_the_old_module_paths_are_gone():
    for old in ("clbeam.geometry", "clbeam.imager", "clbeam.ping"):
        assert importlib.util.find_spec(old) is None, old
