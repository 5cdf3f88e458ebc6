"""The package layout of photogram.mocap (docs/mocap.md, "Package layout"):
which subpackage may import which, imports inside functions included, and
nothing above mocap in the library's layers."""

import ast
from pathlib import Path

import photogram

ROOT = Path(photogram.__file__).parent
MOCAP = ROOT / "mocap"

# part of photogram.mocap -> the parts of photogram.mocap it may import
ALLOWED = {
    "body": set(),
    "motion": set(),
    "tracking": {"body"},
    "sources": {"body", "tracking"},
    "reconstruction": {"body", "motion"},
    "evaluation": {"body"},
    "files": {"body", "tracking", "sources", "motion", "reconstruction", "evaluation"},
    "outputs": {"body", "tracking", "sources", "motion", "reconstruction", "evaluation", "files"},
    "comparisons": {"body", "reconstruction", "evaluation", "files"},
    "stages": {"body", "tracking", "sources", "motion", "reconstruction", "evaluation", "files"},
    "pipeline": {"body", "tracking", "sources", "motion", "reconstruction", "evaluation", "files",
                 "outputs", "comparisons", "stages"},
}
ABOVE = ("photogram.simulation", "photogram.commands", "photogram.report", "photogram.montecarlo",
         "photogram.jump", "photogram.measure", "photogram.demo", "photogram_cli")


def _imports(path: Path):
    """Every module named by an import statement of the file (anywhere in it)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module
            if node.module in ("photogram", "photogram.mocap"):     # from photogram.mocap import x
                yield from (f"{node.module}.{a.name}" for a in node.names)


def _part(path: Path) -> str:
    rel = path.relative_to(MOCAP)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def test_mocap_imports_follow_the_layout():
    bad = []
    files = sorted(MOCAP.rglob("*.py"))
    assert len(files) > 30
    for path in files:
        if path == MOCAP / "__init__.py":
            continue
        part = _part(path)
        assert part in ALLOWED, f"{path}: a new part of photogram.mocap, add it to the layout"
        for name in _imports(path):
            if name.startswith(ABOVE):
                bad.append(f"{path.relative_to(ROOT)} imports {name}")
            elif name.startswith("photogram.mocap."):
                other = name.split(".")[2]
                if other != part and other in ALLOWED and other not in ALLOWED[part]:
                    bad.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not bad, "\n".join(bad)


def test_subpackage_inits_import_nothing():
    for part in ("body", "tracking", "motion", "reconstruction", "evaluation"):
        assert not list(_imports(MOCAP / part / "__init__.py")), part
