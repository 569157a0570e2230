"""The configuration reference page cannot drift or miss a key, and `show` prints what loads."""

from __future__ import annotations

import functools
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml
from hydra import compose, initialize_config_dir

from graspstab.config import load_config
from graspstab.config.compose import compose_config
from graspstab.config.docs import COMMAND, MISSING, NO_DESCRIPTION, get, render
from graspstab.config.show import parse_snakemake_config

REPO = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO / "config"
SCHEMA = REPO / "workflow" / "schemas" / "config.schema.yaml"
PAGE = REPO / "docs" / "configuration.md"
ENV_VARIABLES = ("GRASPSTAB_YCB_DIR", "GRASPSTAB_HAND_DIR", "GRASPSTAB_CACHE_DIR")


@pytest.fixture(scope="module")
def page() -> str:
    return PAGE.read_text()


@pytest.fixture(scope="module")
def schema() -> dict[str, Any]:
    return yaml.safe_load(SCHEMA.read_text())


@pytest.fixture(scope="module")
def default_cfg() -> dict[str, Any]:
    return load_config(CONFIG_DIR, SCHEMA, {}, check_files=False)


def _resolve(node: dict[str, Any], schema: dict[str, Any]) -> dict[str, Any]:
    """``node`` with its ``$ref`` merged in (sibling properties added to the target's)."""
    while "$ref" in node:
        target = schema["$defs"][node["$ref"].rsplit("/", 1)[-1]]
        props = {**target.get("properties", {}), **node.get("properties", {})}
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}, "properties": props}
    return node


def _documented_paths(value: Any, node: dict[str, Any], schema: dict[str, Any], path: str = ""):
    """The row each leaf of the config needs: its own, or its entry's in a mapping of free names
    (object ids, presets, searched parameters), whose fields are shown inline."""
    node = _resolve(node, schema)
    if not isinstance(value, dict):
        yield path
        return
    props = node.get("properties") or {}
    for key, sub in value.items():
        child = f"{path}.{key}" if path else str(key)
        if key in props:
            yield from _documented_paths(sub, props[key], schema, child)
        else:
            yield child


def _schema_leaf_paths(node: dict[str, Any], schema: dict[str, Any], path: str = ""):
    """Every schema property path with no properties below it; a free name is ``<...>``."""
    node = _resolve(node, schema)
    props = node.get("properties") or {}
    extra = node.get("additionalProperties")
    if not props and not isinstance(extra, dict):
        yield path
    for key, sub in props.items():
        yield from _schema_leaf_paths(sub, schema, f"{path}.{key}" if path else key)
    if isinstance(extra, dict):
        yield from _schema_leaf_paths(extra, schema, f"{path}.<*>")


def _cli(
    *args: str, cwd: Path = REPO, module: str = "graspstab.config"
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", module, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
    )


# The page.


def test_page_is_generated(page):
    assert render(CONFIG_DIR, SCHEMA) == page, (
        f"docs/configuration.md is out of date with config/ or the schema: run `{COMMAND}` "
        "from the repository root"
    )


def test_page_does_not_depend_on_the_environment(page, monkeypatch, tmp_path):
    for name in ENV_VARIABLES:
        monkeypatch.setenv(name, str(tmp_path / name))
    assert render(CONFIG_DIR, SCHEMA) == page


def test_every_leaf_of_the_default_config_has_a_row(page, schema, default_cfg):
    missing = [
        p for p in _documented_paths(default_cfg, schema, schema) if f"| `{p}` |" not in page
    ]
    assert not missing, f"keys without a row in docs/configuration.md: {missing}; run `{COMMAND}`"


def test_every_schema_property_has_a_row(page, schema):
    rows = set(re.findall(r"^\| `([^`]+)` \|", page, flags=re.M))
    pattern = {re.sub(r"<\w+>", "<*>", r) for r in rows}
    missing = [p for p in _schema_leaf_paths(schema, schema) if p not in pattern]
    assert not missing, f"schema keys without a row in docs/configuration.md: {missing}"


def test_every_row_is_described_and_timeless(page):
    undescribed = [
        line.split("|")[1].strip() for line in page.splitlines() if NO_DESCRIPTION in line
    ]
    assert not undescribed, (
        f"keys without a description: {undescribed}; add a comment beside the key in its "
        f"config/<group>/ file (or a description in the schema), then run `{COMMAND}`"
    )
    assert not re.search(r"\bissues?\b", page, flags=re.I), "the page names an issue: reword it"


def test_profiles_are_listed(page):
    # keys the study profile file sets appear in its table
    study = page.split("### study", 1)[1].split("### thesis", 1)[0]
    assert "| `creep_free.seeds` | `null` | `[42]` |" in study
    assert "| group `energy` | `reference` | `hpen` |" in study


# Every group and profile is on the page, and each profile's values are the composed ones.

PROFILES = sorted(p.stem for p in (CONFIG_DIR / "profile").glob("*.yaml"))
UNSET = "<not set>"
_ROW = re.compile(r"^\| (group )?`([^`]+)` \| (not set|`[^`]*`) \| (not set|`[^`]*`) \|", re.M)
_BACK = re.compile(r"(the group choice )?`([^`]+)` \((not set|`[^`]*`)\)")


def _section(page: str, heading: str) -> str:
    return page.split(f"\n{heading}\n", 1)[1].split("\n## ", 1)[0]


def test_every_group_and_profile_is_listed(page):
    row = re.compile(r"^\| `([^`@]+)(?:@[^`]*)?` \| [^|]+ \| ([^|]+) \|", re.M)
    options = {m[1]: m[2] for m in row.finditer(_section(page, "## Groups"))}
    for group in sorted(p for p in CONFIG_DIR.iterdir() if p.is_dir()):
        assert group.name in options, f"group {group.name} has no row in the Groups table"
        for option in group.glob("*.yaml"):
            assert f"`{option.stem}`" in options[group.name], (group.name, option.stem)
    headings = re.findall(r"^### (\w+)", _section(page, "## Profiles"), flags=re.M)
    assert sorted(headings) == PROFILES


@functools.cache
def _composed(override: str) -> tuple[dict[str, Any], dict[str, str]]:
    """The resolved configuration (the workflow's compose function) and the group choices."""
    cfg = compose_config(CONFIG_DIR, [override])
    with initialize_config_dir(config_dir=str(CONFIG_DIR), version_base="1.3"):
        hydra_cfg = compose(config_name="config", overrides=[override], return_hydra_config=True)
    choices = hydra_cfg.hydra.runtime.choices
    return cfg, {k: v for k, v in choices.items() if not k.startswith("hydra/")}


def _value(cell: str) -> Any:
    return UNSET if cell == "not set" else yaml.safe_load(cell.strip("`"))


def _at(tree: Any, path: str) -> Any:
    value = get(tree, path)
    return UNSET if value is MISSING else value


def _leaves(tree: dict[str, Any], prefix: str = "") -> list[str]:
    out = []
    for key, value in tree.items():
        deeper = isinstance(value, dict) and value
        out += _leaves(value, f"{prefix}{key}.") if deeper else [f"{prefix}{key}"]
    return out


@pytest.mark.parametrize("name", PROFILES)
def test_profile_values_are_the_composed_ones(page, name):
    """Every value the page states for a profile (its table, and the keys it says the profile
    leaves at their group defaults) is what `profile=<name>` composes to, its defaults list
    (another profile, group overrides) applied; every key that differs from the groups' defaults
    is stated, or summed up under its package ("N keys under `objects`")."""
    parts = re.split(r"^### (\w+).*$", _section(page, "## Profiles"), flags=re.M)
    section = dict(zip(parts[1::2], parts[2::2], strict=True))[name]
    cfg, choices = _composed(f"profile={name}")
    base, base_choices = _composed("~profile")
    wrong, keys, groups = [], set(), set()
    for group, key, default, value in _ROW.findall(section):
        (groups if group else keys).add(key)
        want, want_default = (
            (choices.get(key, UNSET), base_choices.get(key, UNSET))
            if group
            else (_at(cfg, key), _at(base, key))
        )
        if _value(value) != want:
            wrong.append(f"{key}: the page says {value}, {name} composes to {want!r}")
        if _value(default) != want_default:
            wrong.append(f"{key}: the page's group default is {default}, not {want_default!r}")
    back = re.search(r"^Keys the \w+ profile sets and \w+ leaves at their group defaults.*$",
                     section, flags=re.M)  # fmt: skip
    for group, key, value in _BACK.findall(back[0] if back else ""):
        want = choices.get(key, UNSET) if group else _at(cfg, key)
        if _value(value) != want:
            wrong.append(f"{key}: the page says {name} leaves it at {value}, not {want!r}")
    assert not wrong, f"profile {name} on docs/configuration.md: {wrong}; run `{COMMAND}`"

    covered = keys | set(re.findall(r"keys under `([^`]+)`", section))
    unstated = [
        path
        for path in dict.fromkeys(_leaves(cfg) + _leaves(base))
        if _at(cfg, path) != _at(base, path)
        and not any(
            f"{path}.".startswith(f"{k}.") or k.startswith(f"{path}.") for k in covered
        )  # fmt: skip
    ]
    changed = [g for g, v in choices.items() if v != base_choices.get(g) and g != "profile"]
    unstated += [g for g in changed if g not in groups]
    assert not unstated, (
        f"profile {name} changes keys docs/configuration.md does not state: {unstated}; "
        f"run `{COMMAND}`"
    )


# `KEY=VALUE` parsing: snakemake's own parser, and the fallback restating it.


ENTRIES = ["profile=study", "train={seeds: [1, 2]}", "seed=7", "overrides=[labels.window_s=0.3]",
           "flag=True", "rate=0.5", "empty=", "objects_list=[014_lemon, 025_mug]"]  # fmt: skip


def test_entries_parse_as_snakemake_parses_them():
    parse_config = pytest.importorskip("snakemake.cli").parse_config
    assert parse_snakemake_config(ENTRIES) == parse_config(ENTRIES)
    assert parse_snakemake_config(ENTRIES)["train"] == {"seeds": ["1", "2"]}  # BaseLoader strings


# The CLI.


def test_show_round_trips_to_load_config(default_cfg):
    out = _cli("show")
    assert out.returncode == 0, out.stderr
    assert yaml.safe_load(out.stdout) == default_cfg


def test_show_profile_study_sets_what_the_profile_says(default_cfg):
    out = _cli("show", "profile=study")
    assert out.returncode == 0, out.stderr
    cfg = yaml.safe_load(out.stdout)
    study = yaml.safe_load((CONFIG_DIR / "profile" / "study.yaml").read_text())
    study.pop("defaults")

    def leaves(tree: dict[str, Any], prefix: str = ""):
        for key, value in tree.items():
            path = f"{prefix}{key}"
            if isinstance(value, dict):
                yield from leaves(value, f"{path}.")
            else:
                yield path, value

    def get(tree: Any, path: str) -> Any:
        for part in path.split("."):
            tree = tree.get(part, "<unset>") if isinstance(tree, dict) else "<unset>"
        return tree

    for path, value in leaves(study):
        assert get(cfg, path) == value, path
    changed = [p for p, _ in leaves(study) if get(cfg, p) != get(default_cfg, p)]
    assert {"profile_name", "train.seeds", "creep_free.enabled"} <= set(changed)
    assert cfg["synthesis"]["energy"]["name"] == "hpen"  # its group choice


def test_show_key_prints_one_subtree():
    out = _cli("show", "--key", "train.threshold", "train={threshold: {min_recall: 0.8}}")
    assert out.returncode == 0, out.stderr
    assert yaml.safe_load(out.stdout) == {"rule": "min_recall", "min_recall": 0.8,
                                          "grid": [0.05, 0.95, 0.005]}  # fmt: skip
    out = _cli("show", "--key", "seed", "seed=7")
    assert (out.returncode, out.stdout.strip()) == (0, "7")


@pytest.mark.parametrize(
    "args, words",
    [
        (["show", "train={nope: 1}"], "nope"),
        (["show", "--key", "train.nope"], "nope"),
        (["show", "labels={label_low: 0.9}"], "label_low"),
    ],
)
def test_bad_values_are_one_line_and_exit_2(args, words):
    out = _cli(*args)
    assert out.returncode == 2, out.stdout
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("graspstab configuration error: "), out.stderr
    assert words in lines[0]


@pytest.mark.parametrize(
    ("module", "args"), [("graspstab.config", ["show"]), ("graspstab.config.docs", [])]
)
def test_outside_the_repository_says_where_to_run(tmp_path, module, args):
    out = _cli(*args, cwd=tmp_path, module=module)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "repository root" in out.stderr and "--config-dir" in out.stderr


def test_the_docs_tool_writes_the_page(page):
    """The page's own command (COMMAND, in its header) prints it, and only the docs tool does:
    the runtime CLI has no page to print."""
    assert COMMAND == "python -m graspstab.config.docs > docs/configuration.md"
    out = _cli(module="graspstab.config.docs")
    assert out.returncode == 0, out.stderr
    assert out.stdout == page
    assert _cli("reference").returncode == 2  # argparse: not a subcommand of the runtime CLI
