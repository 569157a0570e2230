"""Package metadata agrees with itself: CITATION.cff, pyproject.toml, graspstab.__version__ and
LICENSE name one version and one licence (a release bumps them together)."""

from __future__ import annotations

import tomllib

import yaml

import graspstab
from tests.conftest import REPO

REFERENCE_TITLE = "Simulation-based sensor-invariant grasp stability prediction model"


def _pyproject() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text())["project"]


def _citation() -> dict:
    return yaml.safe_load((REPO / "CITATION.cff").read_text())


def test_citation_version_matches_pyproject_and_package() -> None:
    cff, project = _citation(), _pyproject()
    assert cff["cff-version"] == "1.2.0"
    assert str(cff["version"]) == project["version"], (
        f"CITATION.cff version {cff['version']} != pyproject.toml version {project['version']}"
    )
    assert graspstab.__version__ == project["version"], (
        f"graspstab.__version__ {graspstab.__version__} != pyproject.toml {project['version']}"
    )


def test_citation_names_the_software_and_the_reference() -> None:
    cff, project = _citation(), _pyproject()
    assert cff["type"] == "software"
    assert cff["title"] == project["name"]
    assert cff["license"] == project["license"]
    # The reference is cited beside the software (references), not instead of it
    # (preferred-citation would replace the software's own citation).
    assert "preferred-citation" not in cff
    titles = [ref["title"] for ref in cff["references"]]
    assert REFERENCE_TITLE in titles, f"the implemented reference is not in references: {titles}"


def test_license_file_matches_pyproject() -> None:
    project = _pyproject()
    assert project["license"] == "MIT"
    text = (REPO / "LICENSE").read_text()
    assert text.splitlines()[0] == "MIT License"
    assert "Copyright (c) 2026 the graspstab developers" in text
    assert "Permission is hereby granted, free of charge" in text
    assert 'THE SOFTWARE IS PROVIDED "AS IS", WITHOUT WARRANTY OF ANY KIND' in text


def test_python_classifiers_name_only_tested_versions() -> None:
    project = _pyproject()
    assert project["requires-python"] == ">=3.11"
    tested = {
        c.rsplit("::", 1)[1].strip()
        for c in project["classifiers"]
        if c.startswith("Programming Language :: Python :: 3.")
    }
    assert tested == {"3.11"}, f"classifiers claim Python {sorted(tested)}; CI tests 3.11 only"
