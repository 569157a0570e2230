"""The marker contract of tests/plugins/markers.py catches what it should: a toy-run or job-running
test without the workflow mark stops the collection, a dynamic request of the toy run fails the
test, and a correctly marked suite passes with the toy run's tests first (each case a small pytest
session of its own, with stand-ins for ``run`` and ``asset_env``)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

from tests.conftest import REPO

CONFTEST = """
import pytest

@pytest.fixture(scope="session")
def run():
    return "toy run"

@pytest.fixture(scope="session")
def asset_env():
    return {}

@pytest.fixture
def report(run):
    return run
"""


def _session(tmp_path: Path, tests: str, *args: str) -> subprocess.CompletedProcess:
    (tmp_path / "conftest.py").write_text(CONFTEST)
    (tmp_path / "test_case.py").write_text("import pytest\n" + textwrap.dedent(tests))
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    workflow: toy\n")
    # its own basetemp: pytest would otherwise number it beside this session's and prune old ones
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "tests.plugins.markers",
           "-p", "no:cacheprovider", "--rootdir", str(tmp_path), "--basetemp",
           str(tmp_path / "basetemp"), str(tmp_path / "test_case.py"), *args]  # fmt: skip
    env = {"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}
    return subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, env=env, timeout=120)


def test_unmarked_toy_run_test_stops_the_collection(tmp_path: Path) -> None:
    proc = _session(
        tmp_path,
        """
        def test_direct(run):
            pass

        def test_through_a_fixture(report):
            pass

        def test_jobs(asset_env):
            pass

        def test_unit():
            pass
        """,
        "-m",
        "not workflow",  # checked before -m deselects: a fast run catches it too
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0 and "marker contract" in out, out
    lacks = "uses the toy run or runs Snakemake jobs but lacks @pytest.mark.workflow"
    for name in ("test_direct", "test_through_a_fixture", "test_jobs"):
        assert f"test_case.py::{name} {lacks}" in out, out
    assert "test_unit" not in out


def test_dynamic_request_of_the_toy_run_fails_the_test(tmp_path: Path) -> None:
    proc = _session(
        tmp_path,
        """
        @pytest.fixture(params=["unit", "report"])
        def either(request):
            return request.param if request.param == "unit" else request.getfixturevalue("report")

        def test_either(either):
            pass
        """,
    )
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0, out
    assert "ERROR at teardown of test_either[report]" in out, out
    assert "test_either[report] uses the toy run" in out and "test_either[unit]" not in out, out


def test_marked_tests_pass_toy_run_first(tmp_path: Path) -> None:
    proc = _session(
        tmp_path,
        """
        def test_unit():
            pass

        @pytest.fixture(params=["unit", pytest.param("report", marks=pytest.mark.workflow)])
        def either(request):
            return request.param if request.param == "unit" else request.getfixturevalue("report")

        def test_either(either):
            pass

        @pytest.mark.workflow
        def test_jobs(asset_env):
            pass

        @pytest.mark.workflow
        def test_direct(report):
            pass
        """,
        "-vv",  # -q -vv: one line per test
        "-n",
        "0",
    )
    assert proc.returncode == 0 and "5 passed" in proc.stdout, proc.stdout + proc.stderr
    ran = [line.split("::")[1].split(" ")[0] for line in proc.stdout.splitlines()
           if line.startswith("test_case.py::")]  # fmt: skip
    assert ran == ["test_direct", "test_either[report]", "test_jobs", "test_unit",
                   "test_either[unit]"]  # fmt: skip
