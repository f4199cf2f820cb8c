"""Imports run one way: the scene layer and the shared geometry never import the engine, its outputs or its
tools, so `blobsim check` validates a scene without loading the compiled step."""

import ast
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "blobcli"
BOTTOM = sorted((PACKAGE / "scene").glob("*.py")) + [PACKAGE / "geometry.py", PACKAGE / "colliders.py"]
ABOVE = ("blobcli.sim", "blobcli.io", "blobcli.tools")


def imported_modules(path: Path):
    """Every module `path` imports, at top level or inside functions, as an absolute dotted name."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            yield module
            yield from (f"{module}.{alias.name}" for alias in node.names)


def test_scene_layer_imports_nothing_above_it():
    wrong = [f"{path.relative_to(ROOT)}: {module}" for path in BOTTOM for module in imported_modules(path)
             if any(module == top or module.startswith(top + ".") for top in ABOVE)]
    assert BOTTOM and not wrong, wrong


def test_the_import_walker_sees_relative_and_nested_imports():
    probe = PACKAGE / "scene" / "parse.py"
    modules = set(imported_modules(probe))
    assert "blobcli.scene.tomlpos" in modules  # `from .tomlpos import ...` at the top
    assert "blobcli.geometry" in modules  # `from ..geometry import ...` inside a function


def test_check_does_not_load_the_compiled_step():
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-X", "importtime", "-m", "blobcli", "check",
                          str(ROOT / "scenes" / "gish.toml")], capture_output=True, text=True, env=env, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    loaded = [line.rsplit("|", 1)[-1].strip() for line in out.stderr.splitlines() if line.startswith("import time:")]
    assert "blobcli.scene.schema" in loaded
    assert not [m for m in loaded if m.endswith("_blobcore") or m.startswith("blobcli.sim")], loaded
