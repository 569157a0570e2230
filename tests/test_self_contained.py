"""The repository stands alone: docs and code cite the reference by title, not a sibling path."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
# What a user who clones the repository has; tests and CI may point at the shared asset copies.
USER_FACING = ["README.md", "docs", "src", "workflow", "config", "Snakefile", "benchmarks"]
OUTSIDE = re.compile(r"\.\./shared|DESIGN\.md|thesis\.txt")


def test_nothing_user_facing_points_outside_the_repository():
    hits = []
    for name in USER_FACING:
        root = REPO / name
        files = [root] if root.is_file() else sorted(p for p in root.rglob("*") if p.is_file())
        for f in files:
            if f.suffix in {".pyc", ".png", ".npz", ".npy", ".parquet"} or "egg-info" in str(f):
                continue
            for i, line in enumerate(f.read_text(errors="replace").splitlines(), 1):
                if OUTSIDE.search(line):
                    hits.append(f"{f.relative_to(REPO)}:{i}: {line.strip()}")
    assert hits == []


def test_the_design_document_is_in_the_repository():
    design = " ".join((REPO / "docs" / "design.md").read_text().split())
    assert "Simulation-based sensor-invariant grasp stability prediction model" in design
    assert "docs/design.md" in (REPO / "README.md").read_text()
