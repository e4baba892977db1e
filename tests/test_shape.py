"""Modules of one job and functions that fit a screen: no module of the package over 600
lines, no function over 80 (ruff's C901 and PLR0915 in pyproject.toml keep their complexity
and statements in bounds too)."""

from __future__ import annotations

import ast
from pathlib import Path

import station

ROOT = Path(station.__file__).resolve().parent
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80


def sources() -> list[Path]:
    return sorted(ROOT.rglob("*.py"))


def test_no_module_is_over_600_lines():
    long = [f"{p.relative_to(ROOT)}: {n}" for p in sources()
            if (n := p.read_text().count("\n")) > MAX_MODULE_LINES]  # fmt: skip
    assert long == []


def test_no_function_is_over_80_lines():
    long = []
    for p in sources():
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                n = (node.end_lineno or node.lineno) - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long.append(f"{p.relative_to(ROOT)}:{node.lineno} {node.name}: {n}")
    assert long == []
