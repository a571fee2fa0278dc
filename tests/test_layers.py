"""The layers import downward only: core and util (the disk cache, progress events),
scene, io, models, session, assembly, then the interfaces (cli, viewer). io sits above
scene, not below as ``DESIGN.md`` draws it: reading a scene file makes scene obstacles,
and what scene took from io (the disk cache, progress events) is infrastructure below
both (``pliant.util``). Every import of a pliant module, those inside functions
included, is checked; none reaches up."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1] / "src" / "pliant"
RANK = {"core": 0, "errors": 0, "data": 0, "util": 0, "scene": 1, "io": 2, "models": 3,
        "session": 4, "assembly": 5, "identify": 5, "cli": 6, "viewer": 6}


def upward_imports() -> set[tuple[str, str]]:
    found = set()
    for path in ROOT.rglob("*.py"):
        rel = path.relative_to(ROOT)
        layer = rel.parts[0].removesuffix(".py")
        if layer not in RANK:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            for name in names:
                parts = name.split(".")
                if parts[0] == "pliant" and len(parts) > 1 and RANK.get(parts[1], -1) > RANK[layer]:
                    found.add((rel.as_posix(), name))
    return found


def test_layers_import_downward_only():
    assert upward_imports() == set(), "imports that reach up a layer"


def test_io_only_reads_files():
    """io never solves: none of its modules imports a model, the session or assembly."""
    assert not {(f, m) for f, m in upward_imports() if f.startswith("io/")
                and m.split(".")[1] in ("models", "session", "assembly")}


def test_no_kernel_takes_more_than_ten_parameters():
    """Kernel arguments travel in named bundles (NamedTuples numba accepts): a kernel
    whose parameter list grows past ten needs a bundle, not another positional array."""
    long = []
    for path in ROOT.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef) and any(
                    "njit" in ast.unparse(d) for d in node.decorator_list):
                if len(node.args.args) > 10:
                    long.append(f"{path.relative_to(ROOT)}:{node.name}")
    assert long == []
