"""The lists the docs give of config groups and profiles are the config tree's, so a new group or
profile cannot go undocumented."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GROUPS = {p.name for p in (REPO / "config").iterdir() if p.is_dir()}
PROFILES = {p.stem for p in (REPO / "config" / "profile").glob("*.yaml")}


def _readme() -> str:
    return (REPO / "README.md").read_text()


def test_readme_names_every_config_group() -> None:
    text = _readme()
    listed = text[text.index("Its groups:") : text.index("every key is in")]
    assert set(re.findall(r"`(\w+)`", listed)) == GROUPS


def test_readme_profile_table_has_every_profile() -> None:
    rows = re.findall(r"^\| `(\w+)`(?: \(default\))? \|", _readme(), flags=re.M)
    assert set(rows) == PROFILES


def test_config_root_and_design_name_every_profile() -> None:
    root = (REPO / "config" / "config.yaml").read_text()
    line = next(x for x in root.splitlines() if x.strip().startswith("- profile:"))
    design = (REPO / "docs" / "design.md").read_text()
    sentence = design[design.index("profiles (`quick`") :][:200]
    for profile in PROFILES:
        assert re.search(rf"\b{profile}\b", line), f"config/config.yaml's profile line: {profile}"
        assert f"`{profile}`" in sentence, f"docs/design.md's profile list lacks {profile}"
