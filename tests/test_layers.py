"""The layers of docs/index.md (issue 17): no import cycles, and the
import-linter contract of setup.cfg catches an import that points up.

Imports inside functions count (grimp reads every import statement of a
module, wherever it is).
"""

from __future__ import annotations

import configparser
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

grimp = pytest.importorskip("grimp", reason="import-linter (and grimp) not installed")

ROOT = Path(__file__).resolve().parents[1]
SETUP_CFG = ROOT / "setup.cfg"


def _strongly_connected(edges: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan,
    iterative: no recursion limit on a long chain)."""
    index, low, on_stack, stack, found = {}, {}, set(), [], []
    counter = 0
    for root in sorted(edges):
        if root in index:
            continue
        work = [(root, iter(edges[root]))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, children = work[-1]
            for w in children:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(edges.get(w, ()))))
                    break
                if w in on_stack:
                    low[v] = min(low[v], index[w])
            else:
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
                        found.append(sorted(comp))
    return found


def _cycle_text(graph, component: list[str]) -> str:
    """One cycle through the component, with the importing lines."""
    members = set(component)
    start = component[0]
    # shortest way back to start from each successor (breadth first)
    for first in sorted(graph.find_modules_directly_imported_by(start) & members):
        path = graph.find_shortest_chain(importer=first, imported=start)
        if path:
            chain = (start,) + tuple(path)
            break
    else:       # pragma: no cover - a component always has a cycle through start
        chain = tuple(component)
    lines = []
    for a, b in zip(chain, chain[1:]):
        details = graph.get_import_details(importer=a, imported=b)
        where = ", ".join(f"l.{d['line_number']}" for d in details)
        lines.append(f"    {a} -> {b} ({where})")
    return "\n".join(lines)


def test_no_import_cycles():
    graph = grimp.build_graph("photogram", "photogram_cli", cache_dir=None)
    edges = {m: sorted(graph.find_modules_directly_imported_by(m))
             for m in graph.modules if m.split(".")[0] in ("photogram", "photogram_cli")}
    cycles = _strongly_connected(edges)
    assert not cycles, "import cycles (imports inside functions included):\n" + "\n".join(
        f"  {', '.join(c)}:\n{_cycle_text(graph, c)}" for c in cycles)


def test_strongly_connected_finds_a_cycle():
    edges = {"a": ["b"], "b": ["c"], "c": ["a", "d"], "d": [], "e": ["e"]}
    assert _strongly_connected(edges) == [["a", "b", "c"]]


def _contract_layers() -> list[str]:
    cfg = configparser.ConfigParser()
    cfg.read(SETUP_CFG, encoding="utf-8")
    raw = cfg["importlinter:contract:layers"]["layers"]
    return [line.strip() for line in raw.splitlines() if line.strip()]


def test_every_package_is_in_the_contract():
    """A new subpackage or top-level module of photogram must be given its
    layer in setup.cfg (and docs/index.md)."""
    named = {m.strip() for layer in _contract_layers() for m in layer.replace(":", "|").split("|")}
    pkg = ROOT / "photogram"
    present = {f"photogram.{p.name}" for p in pkg.iterdir()
               if p.is_dir() and (p / "__init__.py").is_file()}
    present |= {f"photogram.{p.stem}" for p in pkg.glob("*.py") if p.stem != "__init__"}
    assert present - named == set(), f"not in the layers contract: {sorted(present - named)}"
    assert named - present - {"photogram_cli"} == set()


def test_docs_index_draws_the_contract():
    """The picture in docs/index.md ("### Layers") shows the layers of the
    contract, top to bottom."""
    text = (ROOT / "docs" / "index.md").read_text(encoding="utf-8")
    section = text[text.index("### Layers"):]
    block = section.split("```")[1]
    drawn = [line.strip() for line in block.splitlines() if line.strip().startswith("photogram")]
    assert drawn == _contract_layers()


def _lint_imports():
    exe = Path(sys.executable).with_name("lint-imports")
    if exe.is_file():
        return [str(exe)]
    if shutil.which("lint-imports"):
        return [shutil.which("lint-imports")]
    pytest.skip("lint-imports (import-linter) is not installed")


def test_contract_fails_on_an_upward_import(tmp_path):
    """A copy of the package with one deliberate upward import (the geometry
    layer importing the commands): lint-imports with the contract of
    setup.cfg reports exactly that import."""
    lint = _lint_imports()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    shutil.copytree(ROOT / "photogram", tmp_path / "photogram", ignore=ignore)
    shutil.copytree(ROOT / "cli", tmp_path / "photogram_cli", ignore=ignore)
    (tmp_path / "photogram" / "geometry" / "upward.py").write_text(
        '"""A deliberate upward import (tests/test_layers.py)."""\n\n'
        "import photogram.commands.bundle  # noqa: F401\n", encoding="utf-8")
    cfg = configparser.ConfigParser()
    cfg.read(SETUP_CFG, encoding="utf-8")
    copy = configparser.ConfigParser()
    for name in cfg.sections():
        if name.startswith("importlinter"):
            copy[name] = dict(cfg[name])
    with open(tmp_path / "setup.cfg", "w", encoding="utf-8") as f:
        copy.write(f)
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    done = subprocess.run(lint + ["--config", str(tmp_path / "setup.cfg"), "--no-cache"],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    out = done.stdout + done.stderr
    assert done.returncode != 0, out
    assert "photogram.geometry is not allowed to import photogram.commands" in out, out
    assert "photogram.geometry.upward -> photogram.commands.bundle (l.3)" in out, out
