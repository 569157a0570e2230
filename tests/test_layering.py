"""The library's layering (declared in tests/layering.py), checked over the source's imports:
every package is a declared stage and imports only the packages it may; no stage imports another
stage's entry module (the workflow scripts run those, and every script runs one); the report loads
no plotting module of the figures package (issue 14), and only its rule graph (report/dag.py)
draws; docs/design.md's stage table is the declaration's."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

import graspstab
from tests import layering
from tests.conftest import REPO

ROOT = Path(graspstab.__file__).resolve().parent
SCRIPTS = REPO / "workflow" / "scripts"
REPORT = ROOT / "report"
DRAWS = {"dag.py"}  # the report's own rule graph: the one report module that may draw
PLOTTING = ("matplotlib", "graspstab.common.plotting")  # what "drawing" imports
FIGURES = "graspstab.figures"
READERS = {FIGURES} | {f"{FIGURES}.{m}" for m in layering.BY_PACKAGE["figures"].public or ()}


def imports_of(path: Path, root: Path | None = None) -> list[tuple[int, str]]:
    """(line, dotted name) of every import in ``path``, at any depth (inside functions too). A
    from-import gives its module and ``module.name`` for each name (the name may be a module); a
    relative one is resolved against the file's place under ``root`` (the graspstab package)."""
    package = None if root is None else ["graspstab", *path.relative_to(root).parts[:-1]]
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                if package is None or node.level > len(package):
                    continue
                base = package[: len(package) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            out.append((node.lineno, module))
            out += [(node.lineno, f"{module}.{a.name}") for a in node.names if a.name != "*"]
    return out


def _modules(root: Path) -> Iterable[tuple[Path, str, list[tuple[int, str]]]]:
    """(file, its package, its graspstab imports) for each module inside a package of ``root``."""
    for f in sorted(root.rglob("*.py")):
        rel = f.relative_to(root)
        if len(rel.parts) < 2:
            continue
        names = [(line, n) for line, n in imports_of(f, root) if n.startswith("graspstab.")]
        yield f, rel.parts[0], names


def packages(root: Path = ROOT) -> set[str]:
    return {p.name for p in root.iterdir() if (p / "__init__.py").is_file()}


def layering_violations(
    root: Path = ROOT, stages: Mapping[str, layering.Stage] = layering.BY_PACKAGE
) -> list[str]:
    """``file:line`` of every import of a package that the importing package may not import, or
    of a module that another package may not import (a package's ``public``)."""
    real = packages(root)
    bad = []
    for f, pkg, names in _modules(root):
        seen = set()
        where = f.relative_to(root).as_posix()
        for line, name in names:
            parts = name.split(".")
            target = parts[1]
            if target == pkg or (target not in stages and target not in real):
                continue  # its own package, or a name of graspstab's __init__
            if (line, target) in seen:
                continue
            if pkg not in stages or target not in stages[pkg].may_import:
                seen.add((line, target))
                bad.append(f"{where}:{line} ({pkg}) imports {name}")
            elif (public := stages[target].public) is not None and len(parts) > 2 \
                    and parts[2] not in public:  # fmt: skip
                seen.add((line, target))
                bad.append(f"{where}:{line} ({pkg}) imports {name}, not one of "
                           f"{target}'s {sorted(public)}")  # fmt: skip
    return bad


def _entry_of(name: str, entries: Iterable[str]) -> str | None:
    return next((e for e in entries if name == e or name.startswith(e + ".")), None)


def entry_imports(
    root: Path = ROOT, entries: Iterable[str] = layering.ENTRY_MODULES
) -> dict[tuple[str, str], str]:
    """(module path under ``root``, entry module) -> ``file:line`` of each import of an entry
    module from outside its own package."""
    entries = sorted(entries)
    out: dict[tuple[str, str], str] = {}
    for f, pkg, names in _modules(root):
        where = f.relative_to(root).as_posix()
        for line, name in names:
            entry = _entry_of(name, entries)
            if entry and entry.split(".")[1] != pkg and (where, entry) not in out:
                out[(where, entry)] = f"{where}:{line} ({pkg}) imports the entry module {entry}"
    return out


def scripts_entries(scripts: Path = SCRIPTS) -> dict[str, set[str]]:
    """Each workflow script's name -> the entry modules it imports."""
    return {
        s.stem: {e for _, n in imports_of(s) if (e := _entry_of(n, layering.ENTRY_MODULES))}
        for s in sorted(scripts.glob("*.py"))
    }


# -- the declaration itself ---------------------------------------------------------------------


def test_every_package_is_declared_in_its_floor() -> None:
    assert packages() == set(layering.BY_PACKAGE), (
        "declare each package of src/graspstab, in its floor, in tests/layering.py STAGES"
    )
    assert len(layering.STAGES) == len(layering.BY_PACKAGE)


def test_a_package_may_import_only_lower_floors() -> None:
    floor = layering.FLOOR
    bad = [f"{s.package} may import {t}" for s in layering.STAGES for t in sorted(s.may_import)
           if t not in floor or floor[t] >= floor[s.package]]  # fmt: skip
    assert bad == []


def test_every_allowed_import_is_used() -> None:
    """The allowed sets stay minimal: a package no longer imported is dropped from the set
    (``common``, the floor under everything, may stay)."""
    used: dict[str, set[str]] = {p: set() for p in layering.BY_PACKAGE}
    for _, pkg, names in _modules(ROOT):
        used.setdefault(pkg, set()).update(n.split(".")[1] for _, n in names)
    unused = [f"{s.package} -> {t}" for s in layering.STAGES
              for t in sorted(s.may_import - used[s.package] - {"common"})]  # fmt: skip
    assert unused == [], "drop these from may_import in tests/layering.py"


def test_declared_entry_modules_exist_and_are_run_by_a_script() -> None:
    run = set().union(*scripts_entries().values())
    for entry in sorted(layering.ENTRY_MODULES):
        _, pkg, *mod = entry.split(".")
        assert pkg in layering.BY_PACKAGE and len(mod) == 1, entry
        assert (ROOT / pkg / f"{mod[0]}.py").is_file(), entry
        assert entry in run, f"no workflow script imports {entry}: not an entry module"


# -- the source against it ----------------------------------------------------------------------


def test_every_import_goes_to_an_allowed_package() -> None:
    bad = layering_violations()
    assert bad == [], "imports the layering does not allow (tests/layering.py):\n" + "\n".join(bad)


def test_no_stage_imports_another_stages_entry_module() -> None:
    found = entry_imports()
    new = [where for key, where in sorted(found.items()) if key not in layering.KNOWN_ENTRY_IMPORTS]
    assert new == [], (
        "import the library module beside the entry module instead (the workflow scripts are "
        "the only importers of an entry module):\n" + "\n".join(new)
    )
    fixed = sorted(set(layering.KNOWN_ENTRY_IMPORTS) - set(found))
    assert fixed == [], f"no longer imported: remove from KNOWN_ENTRY_IMPORTS: {fixed}"


def test_every_workflow_script_runs_an_entry_module() -> None:
    entries = scripts_entries()
    assert len(entries) > 20
    bad = [s for s, e in entries.items() if not e and s not in layering.SCRIPTS_WITHOUT_ENTRY]
    assert bad == [], (
        "these scripts run no declared entry module: declare the module whose function they run "
        "in ENTRY_MODULES, or list the script in SCRIPTS_WITHOUT_ENTRY with a reason: "
        + ", ".join(bad)
    )
    stale = [s for s in layering.SCRIPTS_WITHOUT_ENTRY if entries.get(s, {"missing"})]
    assert stale == [], "remove from SCRIPTS_WITHOUT_ENTRY"


def test_the_checks_catch_planted_violations(tmp_path) -> None:
    fake = tmp_path / "graspstab"
    for pkg in ("replay", "labels", "closedloop"):
        (fake / pkg).mkdir(parents=True)
        (fake / pkg / "__init__.py").write_text("")
    # an upward import inside a function, and a relative one
    (fake / "replay" / "bad.py").write_text(
        "def f():\n    from graspstab.labels.interval import usable_interval\n"
        "    from ..labels import windows\n"
    )
    # an allowed package, but another stage's entry module (a module-level from-import of it)
    (fake / "closedloop" / "reach.py").write_text(
        "import numpy\nfrom graspstab.replay import replay_grasps\n"
    )
    # a package's own entry module: fine
    (fake / "replay" / "own.py").write_text("from graspstab.replay.replay_grasps import x\n")
    assert layering_violations(fake) == [
        "replay/bad.py:2 (replay) imports graspstab.labels.interval",
        "replay/bad.py:3 (replay) imports graspstab.labels",
    ]
    assert list(entry_imports(fake).values()) == [
        "closedloop/reach.py:2 (closedloop) imports the entry module graspstab.replay.replay_grasps"
    ]
    # a workflow script that runs no entry module
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    (scripts / "helper_only.py").write_text("from graspstab.common.jobs import job\n")
    (scripts / "runs.py").write_text("from graspstab.learning import tune_model\n")
    assert scripts_entries(scripts) == {
        "helper_only": set(),
        "runs": {"graspstab.learning.tune_model"},
    }
    # a plotting module of the figures package, from the report
    (fake / "report").mkdir()
    (fake / "report" / "x.py").write_text(
        "from graspstab.figures import presentation, baseline\n"
        "from graspstab.figures.artefacts import StudyArtefacts\n"
    )
    (fake / "figures").mkdir()
    (fake / "figures" / "__init__.py").write_text("")
    assert layering_violations(fake) == [
        "replay/bad.py:2 (replay) imports graspstab.labels.interval",
        "replay/bad.py:3 (replay) imports graspstab.labels",
        "report/x.py:1 (report) imports graspstab.figures.baseline, not one of figures's "
        "['artefacts', 'presentation']",
    ]


# -- training and evaluation ---------------------------------------------------------------------

# What training may take from the scores of graspstab.metrics: the validation score that picks
# the best epoch and the validation threshold rule (3.5.2-3.5.3), both model selection. Test
# metrics, per-object tables, curves and every study statistic are the evaluation package's.
MODEL_SELECTION = {
    "graspstab.metrics.classification." + n
    for n in ("binary_metrics", "select_threshold", "threshold_grid", "ThresholdChoice",
              "UNDEFINED_THRESHOLD")
}  # fmt: skip


def test_training_computes_no_evaluation_statistic() -> None:
    """No module of learning/ needs evaluation/ (or anything above it), and from metrics it takes
    only what model selection needs; the scored test split is evaluation.tested_run's."""
    taken = {}
    for f in sorted((ROOT / "learning").rglob("*.py")):
        for line, name in imports_of(f, ROOT):
            where = f"learning/{f.name}:{line}"
            assert not name.startswith(("graspstab.evaluation", "graspstab.figures")), where
            if name.startswith("graspstab.metrics.") and name.count(".") == 3:
                taken[name] = where
    beyond = {n: w for n, w in taken.items() if n not in MODEL_SELECTION}
    assert not beyond, f"training computes evaluation statistics: {beyond}"
    assert "select_threshold" in "".join(taken)  # the check sees the imports it guards


# -- the report and the plotting modules (issue 14) ---------------------------------------------


def test_no_report_module_imports_a_plotting_module() -> None:
    modules = sorted(p.name for p in REPORT.glob("*.py"))
    assert {"learning.py", "headline.py", "write_report.py", "dag.py"} <= set(modules)
    for name in modules:
        imported = {n for _, n in imports_of(REPORT / name, ROOT)}
        figures = {m for m in imported if m.startswith(FIGURES + ".")}
        assert not {m for m in figures if ".".join(m.split(".")[:3]) not in READERS}, name
        if name not in DRAWS:
            draws = {m for m in imported for p in PLOTTING if m == p or m.startswith(p + ".")}
            assert not draws, f"report/{name} draws: only {sorted(DRAWS)} may"


def test_importing_the_report_loads_no_plotting_module() -> None:
    """At run time too, through every indirect import (a subprocess: a fresh sys.modules)."""
    code = (
        "import sys\n"
        "import graspstab.report.learning, graspstab.report.headline\n"
        "import graspstab.figures.presentation, graspstab.figures.artefacts\n"
        f"print(any(m in sys.modules for m in {PLOTTING!r}))\n"
        "import graspstab.report.write_report\n"
        f"print(any(m.startswith({FIGURES!r}) and m not in {READERS!r} for m in sys.modules))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.split() == ["False", "False"], proc.stdout


# -- the design doc's table ---------------------------------------------------------------------


def test_design_doc_stage_table_is_the_declaration() -> None:
    inner = layering.table_in(layering.DESIGN.read_text())
    assert inner is not None, (
        f"docs/design.md needs one {layering.TABLE_START} ... {layering.TABLE_END} pair"
    )
    assert inner.strip("\n") == layering.render_table().strip("\n"), (
        "docs/design.md's stage table is out of date: regenerate it from tests/layering.py with "
        "`python -m tests.layering --write` (or paste `python -m tests.layering` between the "
        "markers)"
    )
