"""The reproduction scripts in docs/ (run by hand, minutes each) cannot rot silently: every name they take from
surgopt exists. An AST pass over each script: ``from surgopt.x import y`` names must be attributes of the module,
and ``alias.attr`` on a surgopt module alias must exist (docs/reproduce_raven.py once called a helper the plans
refactor had removed, and stopped before its last lines)."""
import ast
import importlib
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
#: The scripts that use surgopt (a script on numpy alone, such as reproduce_raven_isotropy.py, has nothing to check).
SCRIPTS = sorted(p for p in DOCS.glob("*.py") if "from surgopt" in p.read_text() or "import surgopt" in p.read_text())


def surgopt_names(tree):
    """(module aliases {name: module}, imported names [(module, name, line)]) of surgopt imports anywhere."""
    aliases, names = {}, []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("surgopt"):
                    aliases[a.asname or a.name.split(".")[0]] = a.name if a.asname else "surgopt"
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("surgopt"):
            for a in node.names:
                full = f"{node.module}.{a.name}"
                try:
                    importlib.import_module(full)
                    aliases[a.asname or a.name] = full
                except ImportError:
                    names.append((node.module, a.name, node.lineno))
    return aliases, names


@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_every_surgopt_name_a_docs_script_uses_exists(script):
    tree = ast.parse(script.read_text())
    aliases, names = surgopt_names(tree)
    assert aliases or names, "the premise: the script takes names from surgopt"
    for module, name, line in names:
        assert hasattr(importlib.import_module(module), name), f"{script.name}:{line}: {module}.{name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in aliases:
            module = importlib.import_module(aliases[node.value.id])
            assert hasattr(module, node.attr), f"{script.name}:{node.lineno}: {aliases[node.value.id]}.{node.attr}"
