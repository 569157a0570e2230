"""Stages import only earlier stages: the library's layering, checked over the source's imports."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import graspstab

# The pipeline's stages in order (README "Layout"): a stage may import itself, any earlier stage,
# and nothing later. ``common`` is below everything; ``config`` checks object ids against the
# asset catalogue, so it sits above ``assets``.
STAGES = [
    "common", "metrics", "assets", "config", "objects", "hand", "synthesis", "replay", "labels",
    "sensing", "learning", "evaluation", "figures", "monitor", "closedloop", "report",
]  # fmt: skip
ROOT = Path(graspstab.__file__).resolve().parent


def imports_of(path: Path) -> list[tuple[int, str]]:
    """(line, dotted module) of every graspstab import in ``path``, at any depth."""
    out = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.append((node.lineno, node.module))
    return [(line, m) for line, m in out if m.startswith("graspstab.")]


def upward_imports() -> list[str]:
    rank = {s: i for i, s in enumerate(STAGES)}
    bad = []
    for f in sorted(ROOT.rglob("*.py")):
        parts = f.relative_to(ROOT).parts
        if len(parts) < 2:
            continue
        for line, module in imports_of(f):
            target = module.split(".")[1]
            if target in rank and rank[target] > rank[parts[0]]:
                bad.append(f"{f.relative_to(ROOT)}:{line} ({parts[0]}) imports {module}")
    return bad


def test_every_package_is_a_listed_stage():
    packages = {p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file()}
    assert packages == set(STAGES), "add the new stage to STAGES in its place"


def test_no_stage_imports_a_later_stage():
    assert upward_imports() == []


def test_the_check_catches_an_upward_import(tmp_path, monkeypatch):
    # the checker itself: a replay module importing the labelling stage inside a function
    fake = tmp_path / "graspstab"
    (fake / "replay").mkdir(parents=True)
    (fake / "replay" / "bad.py").write_text(
        "def f():\n    from graspstab.labels.figure import shade_periods\n"
    )
    monkeypatch.setattr(sys.modules[__name__], "ROOT", fake)
    assert upward_imports() == ["replay/bad.py:2 (replay) imports graspstab.labels.figure"]
