"""The report imports no plotting module of the figures package (issue 14): its tables, headline
and learning section read names and rules from graspstab.figures.presentation and
graspstab.figures.artefacts, which import no matplotlib; only report/dag.py draws (the report's own
rule graph)."""

from __future__ import annotations

import ast
import subprocess
import sys

from tests.conftest import REPO

REPORT = REPO / "src" / "graspstab" / "report"
PLOTTING = "graspstab.figures"
READERS = {"graspstab.figures", "graspstab.figures.presentation", "graspstab.figures.artefacts"}
DRAWS = {"dag.py"}  # the report's own DAG figure


def _imports(path: str) -> set[str]:
    tree = ast.parse((REPORT / path).read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
            names |= {f"{node.module}.{a.name}" for a in node.names}
    return names


def test_no_report_module_imports_a_plotting_module() -> None:
    modules = sorted(p.name for p in REPORT.glob("*.py"))
    assert {"learning.py", "headline.py", "write_report.py"} <= set(modules)
    for name in modules:
        imported = _imports(name)
        assert not {m for m in imported if m.startswith(PLOTTING) and m not in READERS
                    and m.rsplit(".", 1)[0] not in READERS - {PLOTTING}}, name
        if name not in DRAWS:
            assert not {m for m in imported if m.split(".")[0] == "matplotlib"}, name


def test_importing_the_report_loads_no_learning_figure_module() -> None:
    """At run time too, through every indirect import (a subprocess: a fresh sys.modules)."""
    code = (
        "import sys\n"
        "import graspstab.report.learning, graspstab.report.headline\n"
        "import graspstab.figures.presentation, graspstab.figures.artefacts\n"
        "print('matplotlib' in sys.modules)\n"
        "import graspstab.report.write_report\n"
        f"print(any(m.startswith({PLOTTING!r}) and m not in {READERS!r} for m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split() == ["False", "False"], proc.stdout
