"""Checks that every public name of the Python package has a docstring.

Read from the sources, so it needs no build (standard library only):

- every public class, function, method and property of ``python/spibench/*.py`` (a name
  without a leading underscore; ``__init__`` and the other dunder methods are covered by their
  class's docstring);
- every class and function of the extension's stubs, ``python/spibench/_spibench.pyi``, which
  the API reference takes its signatures from;
- every ``#[pyclass]``, ``#[pyfunction]`` and method of a ``#[pymethods]`` block of the
  binding (``python/src/*.rs``), whose ``///`` doc comment pyo3 exposes as ``__doc__``.

Usage: ``python3 python/check_docstrings.py`` (exit status 1 and one line per missing
docstring). CI runs it in its Python stage, and ``python/tests/test_docstrings.py`` runs it
with the tests.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path
from typing import List

HERE = Path(__file__).resolve().parent


def _public(name: str) -> bool:
    return not name.startswith("_")


def _python(path: Path) -> List[str]:
    """The public definitions of a module (or stub) without a docstring."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    rel = path.relative_to(HERE.parent)
    missing = []
    if ast.get_docstring(tree) is None and path.suffix == ".py":
        missing.append(f"{rel}: the module")

    def visit(body, owner: str) -> None:
        for node in body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                if not _public(node.name):
                    continue
                # An overload or a property's setter shares the first definition's docstring.
                decorators = [ast.unparse(d) for d in node.decorator_list]
                if any(d.endswith(".setter") or d.endswith("overload") for d in decorators):
                    continue
                if ast.get_docstring(node) is None:
                    missing.append(f"{rel}:{node.lineno}: {owner}{node.name}")
                if isinstance(node, ast.ClassDef):
                    visit(node.body, f"{owner}{node.name}.")

    visit(tree.body, "")
    return missing


# A `///` doc comment, then attributes, then the item.
_RUST_ITEM = re.compile(r"^\s*(pub(\([a-z]+\))?\s+)?(struct|enum|fn)\s+([A-Za-z0-9_]+)")


def _rust(path: Path) -> List[str]:
    """The binding's Python-visible classes, functions and methods without a doc comment."""
    rel = path.relative_to(HERE.parent)
    lines = path.read_text(encoding="utf-8").splitlines()
    missing = []
    in_methods = False
    depth = 0
    for i, line in enumerate(lines):
        t = line.strip()
        if t.startswith("#[pymethods]"):
            in_methods, depth = True, 0
        m = _RUST_ITEM.match(line)
        if m is None:
            if in_methods:
                depth += line.count("{") - line.count("}")
                if depth <= 0 and "}" in line:
                    in_methods = False
            continue
        kind, name = m.group(3), m.group(4)
        # The attributes and doc comment above the item.
        j = i - 1
        attrs, doc = [], False
        while j >= 0 and (lines[j].strip().startswith("#[") or lines[j].strip().startswith("///")
                          or lines[j].strip().startswith("//") or lines[j].strip().endswith(")]")):
            s = lines[j].strip()
            if s.startswith("///"):
                doc = True
            elif s.startswith("#["):
                attrs.append(s)
            j -= 1
        exposed = any(a.startswith(("#[pyclass", "#[pyfunction")) for a in attrs)
        if any(a.startswith("#[new]") for a in attrs):
            continue  # the class docstring covers the constructor
        # Every method of a #[pymethods] block is exposed to Python.
        method = in_methods and kind == "fn" and line.startswith("    ") and \
            not line.startswith("     ")
        if method and name.startswith("__"):
            method = False
        if (exposed or method) and not doc:
            missing.append(f"{rel}:{i + 1}: {name}")
        if in_methods:
            depth += line.count("{") - line.count("}")
            if depth <= 0 and "}" in line:
                in_methods = False
    return missing


def missing() -> List[str]:
    """Every public name without a docstring, as ``file:line: name``."""
    out: List[str] = []
    for path in sorted((HERE / "spibench").glob("*.py")) + [HERE / "spibench" / "_spibench.pyi"]:
        out += _python(path)
    for path in sorted((HERE / "src").glob("*.rs")):
        out += _rust(path)
    return out


def main() -> int:
    names = missing()
    for n in names:
        print(f"no docstring: {n}", file=sys.stderr)
    if names:
        print(f"{len(names)} public names of the Python package lack a docstring", file=sys.stderr)
        return 1
    print("every public name of the Python package has a docstring")
    return 0


if __name__ == "__main__":
    sys.exit(main())
