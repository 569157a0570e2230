"""Configuration: Hydra composition, overrides, schema and object-set validation messages."""

from __future__ import annotations

import copy
import re
from pathlib import Path

import pytest

from graspstab.config import ConfigError, compose_config, load_config, split_snakemake_config
from graspstab.config.credentials import mask_text, strip_password, url_password
from graspstab.config.validate import (
    ENTRY_KEYS,
    ID_PATTERN,
    load_schema,
    object_entry_schema,
    validate_config,
    validate_schema,
)
from tests.conftest import CONFIG_DIR, SCHEMA

REFERENCE_SPLIT = {
    "train": {
        "061_foam_brick",
        "009_gelatin_box",
        "014_lemon",
        "025_mug",
        "006_mustard_bottle",
        "002_master_chef_can",
        "008_pudding_box",
        "026_sponge",
    },
    "val": {"013_apple", "010_potted_meat_can"},
    "test": {"016_pear", "077_rubiks_cube"},
}


@pytest.fixture(scope="module")
def default_cfg() -> dict:
    return compose_config(CONFIG_DIR, [])


def test_default_config_matches_schema(default_cfg):
    # A test that fails when the default config drifts from the schema (DESIGN.md habit).
    validate_schema(default_cfg, SCHEMA)


def test_default_object_set_is_reference_split(default_cfg):
    items = default_cfg["objects"]["items"]
    got = {s: {o for o, e in items.items() if e["split"] == s} for s in REFERENCE_SPLIT}
    assert got == REFERENCE_SPLIT
    assert all(e["mass"] > 0 for e in items.values())


def test_reference_constants(default_cfg):
    c = default_cfg
    # eq. 16 exactly in the reference energy; our documented w_fc and the added w_hpen in hpen
    # (README "Grasp synthesis")
    eq16 = {"dis": 100.0, "fc": 1.0, "pen": 10.0, "spen": 100.0, "joint": 1000.0, "hpen": 0.0}
    assert _compose({"energy": "reference"})["synthesis"]["energy"]["weights"] == eq16
    assert _compose({"energy": "hpen"})["synthesis"]["energy"]["weights"] == dict(
        eq16, fc=0.01, hpen=10000.0
    )
    assert c["synthesis"]["annealing"]["iterations"] == 6000
    assert c["replay"]["timestep"] == 0.0005 and c["replay"]["steps"] == 40000
    assert c["labels"]["v_slip"] == 0.0012
    assert c["preprocess"]["hull_points"]["count"] == 2000
    assert c["hand"]["candidates"]["points_per_region"] == 12
    assert c["profile_name"] == "quick"


def test_profiles_protocol_choices():
    """Quick and study deviate by name (our energy, a squeeze), the thesis profile keeps every
    reference choice, and a group choice on the command line beats a profile's."""
    quick, thesis, study = (_compose({"profile": p}) for p in ("quick", "thesis", "study"))
    assert compose_config(CONFIG_DIR, []) == quick  # quick is the default
    for cfg in (quick, study):
        assert cfg["synthesis"]["energy"]["name"] == "hpen"
        assert cfg["replay"]["squeeze"]["angle"] == 0.25
        assert cfg["synthesis"]["split_shards"] == {"train": None, "val": 2, "test": None}
        # 32 grasps a shard in seed blocks of 16: the grasps of 16-grasp shards
        assert (cfg["synthesis"]["grasps_per_shard"], cfg["synthesis"]["seed_block"]) == (32, 16)
    assert thesis["replay"]["contact"]["name"] == "reference"
    assert thesis["synthesis"]["energy"]["name"] == "reference"
    assert thesis["replay"]["squeeze"]["angle"] == 0.0
    assert set(thesis["synthesis"]["split_shards"].values()) == {None}
    assert all(c["replay"]["contact"]["name"] == "reference" for c in (quick, study))
    assert _compose({"energy": "reference"})["synthesis"]["energy"]["name"] == "reference"
    swapped = _compose({"profile": "thesis", "energy": "hpen"})
    assert swapped["synthesis"]["energy"]["name"] == "hpen"
    assert _compose({"contact": "strict"})["replay"]["contact"]["cone"] == "elliptic"
    # the study profile: the whole protocol at reduced counts, >= 3 seeds for the baselines (2 for
    # the sweep, a third of the profile's job-seconds at three), sweep 0.01-0.5 s
    assert len(study["train"]["seeds"]) >= 3 and len(study["sweep"]["seeds"]) >= 2
    assert min(study["sweep"]["windows_s"]) == 0.01 and max(study["sweep"]["windows_s"]) == 0.5
    # ... with 3.4.3's sweep configurations and the creep-free benchmark (issue 15); quick keeps
    # the tuned configurations and leaves the benchmark off
    assert study["sweep"]["configuration"] == "reference" and study["creep_free"]["enabled"]
    assert quick["sweep"]["configuration"] == "tuned" and not quick["creep_free"]["enabled"]
    # the sensor-robustness study (issue 17): every profile runs it; quick at one seed, three
    # strengths and one augmented family, the study at every seed and four strengths
    assert all(c["sensing"]["robustness"] for c in (quick, study, thesis))
    assert quick["sensing"]["seeds"] == [42] and quick["sensing"]["augment"]["families"] == ["lstm"]
    assert {len(v) for v in quick["sensing"]["curves"].values()} == {3}
    assert study["sensing"]["seeds"] is None and study["sensing"]["augment"]["seeds"] == [42]
    assert {len(v) for v in study["sensing"]["curves"].values()} == {4}
    assert study["sensing"]["augment"]["families"] == ["cnn", "gru", "lstm"]
    # the input audit: quick on the LSTM at one seed, the study on every family at one seed
    assert quick["audit"]["families"] == ["lstm"] and quick["audit"]["seeds"] == [42]
    assert study["audit"]["families"] == ["cnn", "gru", "lstm"] and study["audit"]["seeds"] == [42]
    assert thesis["audit"]["seeds"] is None and thesis["audit"]["enabled"]
    for cfg in (quick, study, thesis):
        validate_schema(cfg, SCHEMA)
    bad = {**quick, "sensing": {**quick["sensing"], "curves": {"blur": [1.0]}}}
    with pytest.raises(Exception, match="blur"):
        validate_schema(bad, SCHEMA)
    # augmentation through the mixture by default (per-corruption runs are one override away),
    # and the latency-aware window scored under the sensors in every profile
    assert all(c["sensing"]["augment"]["modes"] == ["mixture"] for c in (quick, study, thesis))
    assert all(c["sensing"]["pick_window"] for c in (quick, study, thesis))
    aug = {**quick["sensing"]["augment"], "modes": ["mixture", "blur"]}
    with pytest.raises(Exception, match="blur"):
        validate_schema({**quick, "sensing": {**quick["sensing"], "augment": aug}}, SCHEMA)


def _compose(snakemake_config: dict) -> dict:
    return compose_config(CONFIG_DIR, *split_snakemake_config(snakemake_config, CONFIG_DIR))


def test_profile_and_nested_overrides():
    cfg = _compose(
        {
            "profile": "thesis",
            "synthesis": {"shards": "3"},
            "only_objects": ["061_foam_brick"],
            "overrides": ["labels.window_s=0.3"],
        }
    )
    assert cfg["profile_name"] == "thesis"
    assert cfg["synthesis"]["shards"] == 3  # the explicit override beats the profile
    assert cfg["synthesis"]["grasps_per_shard"] == 128  # from the thesis profile
    assert cfg["only_objects"] == ["061_foam_brick"]
    assert cfg["labels"]["window_s"] == 0.3


def test_override_values_keep_types():
    cfg = _compose(
        {
            "sweep": {"windows_s": ["0.1", "0.2"]},
            "seed": 7,
            "assets": {"ycb_dir": "/tmp/some dir"},
            "objects": {"items": {"014_lemon": {"mass": "0.03"}}},
        }
    )
    assert cfg["objects"]["items"]["014_lemon"]["mass"] == 0.03
    assert cfg["sweep"]["windows_s"] == [0.1, 0.2]
    assert cfg["seed"] == 7
    assert cfg["assets"]["ycb_dir"] == "/tmp/some dir"


def test_env_var_sets_local_asset_dirs(monkeypatch, tmp_path):
    monkeypatch.setenv("GRASPSTAB_YCB_DIR", str(tmp_path))
    monkeypatch.delenv("GRASPSTAB_HAND_DIR", raising=False)
    cfg = compose_config(CONFIG_DIR, [])
    assert cfg["assets"]["ycb_dir"] == str(tmp_path)
    assert cfg["assets"]["hand_dir"] is None


def test_misspelt_key_is_rejected(default_cfg):
    bad = copy.deepcopy(default_cfg)
    bad["replay"]["timestpe"] = 0.001
    with pytest.raises(ConfigError, match="replay") as err:
        validate_schema(bad, SCHEMA)
    assert "unknown key 'timestpe' (did you mean 'timestep'?)" in str(err.value)


def test_unknown_override_key_fails_at_compose():
    with pytest.raises(ConfigError):
        compose_config(CONFIG_DIR, ["replay.no_such_key=1"])
    with pytest.raises(ConfigError, match="no_such_key"):
        _compose({"replay": {"no_such_key": "1"}})
    with pytest.raises(ConfigError):
        _compose({"profile": "no_such_profile"})


@pytest.mark.parametrize(
    ("override", "says", "never"),
    [
        ({"tune": {"trails": "3"}},
         ["unknown key 'trails' (did you mean 'trials'?) at tune", "trials, window_s"], []),
        ({"objects": {"items": {"014_lemon": {"mas": "0.2"}}}},
         ["unknown key 'mas' (did you mean 'mass'?) at objects.items.014_lemon",
          "split, mass, shape, sha256, mesh, rotation_deg"], ["mass missing", "None"]),
        ({"objects": {"items": {"014_lemon": {"mesh": "/x.obj"}}}},
         ["objects.items.014_lemon", "has no 'mesh'", "object set file"], ["spelling"]),
        ({"objects": {"items": {"bad id!": {"mesh": "/x.obj"}}}},
         ["object 'bad id!'", "not add one", "README \"Add an object\""], []),
    ],
)  # fmt: skip
def test_unknown_override_key_says_which_and_the_closest(override, says, never):
    """A key the composed tree lacks is named with its dotted place and the closest known key;
    an object entry's field the set's file lacks, and an object not in the set, say where to add
    them (an object file), not how to spell them."""
    with pytest.raises(ConfigError) as err:
        _compose(override)
    msg = str(err.value)
    for text in says:
        assert text in msg, msg
    for text in never:
        assert text not in msg, msg


def _with_entry(cfg: dict, object_id: str, **changes) -> dict:
    bad = copy.deepcopy(cfg)
    entry = dict(bad["objects"]["items"].get(object_id, {"split": "train", "mass": 0.1}))
    entry.update(changes)
    bad["objects"]["items"][object_id] = entry
    return bad


@pytest.mark.parametrize(
    ("object_id", "changes", "field"),
    [
        ("999_not_an_object", {}, "'id'"),
        ("014_lemon", {"split": "training"}, "'split'"),
        ("014_lemon", {"mass": 0.0}, "'mass'"),
        ("014_lemon", {"mass": -1.0}, "'mass'"),
        ("014_lemon", {"mesh": "/nonexistent/lemon.obj"}, "'mesh'"),
    ],
)
def test_bad_object_entry_names_entry_and_field(default_cfg, object_id, changes, field):
    bad = _with_entry(default_cfg, object_id, **changes)
    with pytest.raises(ConfigError) as err:
        validate_config(bad, SCHEMA)
    msg = str(err.value)
    assert object_id in msg and field in msg and "ycb12" in msg


def test_misspelt_object_key_is_named_not_missing(default_cfg):
    """`mas: 0.029` in an object set is an unknown key with its likely meaning, not a missing
    mass."""
    bad = _with_entry(default_cfg, "014_lemon", mas=0.029)
    del bad["objects"]["items"]["014_lemon"]["mass"]
    with pytest.raises(ConfigError) as err:
        validate_config(bad, SCHEMA, check_files=False)
    msg = str(err.value)
    assert "object '014_lemon' in object set 'ycb12' (config/objects/ycb12.yaml)" in msg
    assert "unknown key 'mas' (did you mean 'mass'?)" in msg
    assert "objects.items.014_lemon.mas" in msg
    assert "field 'mass'" not in msg and "None" not in msg


@pytest.mark.parametrize(
    ("object_id", "suggestion"),
    [("bad id!", "900_bad_id"), ("My_Cup", "900_my_cup"), ("014_Lemon", "014_lemon"),
     ("14_lemon", "900_14_lemon")],
)  # fmt: skip
def test_bad_object_id_names_the_rule_and_a_fix(default_cfg, object_id, suggestion):
    """An id outside the rule, even with its own mesh, is named with the field, the rule and a
    name that follows it (not jsonschema's raw message)."""
    bad = _with_entry(default_cfg, object_id, mesh="/x.obj")
    with pytest.raises(ConfigError) as err:
        validate_config(bad, SCHEMA, check_files=False)
    msg = str(err.value)
    assert f"object {object_id!r} in object set 'ycb12'" in msg and "field 'id'" in msg
    assert f"does not follow the object id rule {ID_PATTERN}" in msg and "three digits" in msg
    assert f"Rename the entry, e.g. to {suggestion!r}" in msg
    assert "does not match" not in msg  # not the schema's wording
    assert re.fullmatch(ID_PATTERN, suggestion)


def test_object_rules_are_the_schemas():
    """The id rule and an entry's keys the messages quote are the schema's."""
    assert object_entry_schema(load_schema(SCHEMA)) == (ID_PATTERN, ENTRY_KEYS)


def test_missing_mesh_in_local_dir_names_entry(default_cfg, tmp_path):
    cfg = copy.deepcopy(default_cfg)
    cfg["assets"]["ycb_dir"] = str(tmp_path)  # empty directory: no meshes
    with pytest.raises(ConfigError) as err:
        validate_config(cfg, SCHEMA)
    msg = str(err.value)
    # names the folder, where it is set and the fixes, not an entry field the object lacks
    assert str(tmp_path) in msg and "assets.ycb_dir" in msg and "only_objects" in msg, msg
    assert "field 'mesh'" not in msg


def test_only_objects_must_be_in_set():
    with pytest.raises(ConfigError, match="only_objects"):
        load_config(CONFIG_DIR, SCHEMA, {"only_objects": ["003_cracker_box"]}, check_files=False)


def test_load_config_with_shared_assets(ycb_dir: Path):
    cfg = load_config(CONFIG_DIR, SCHEMA, {"assets": {"ycb_dir": str(ycb_dir)}})
    assert cfg["assets"]["ycb_dir"] == str(ycb_dir)


# Bad values a user can type, as `snakemake --config` hands them over (YAML BaseLoader: every
# leaf a string): each must fail at load time, naming the field(s).
@pytest.mark.parametrize(
    ("override", "named"),
    [
        ({"labels": {"label_low": "0.7", "label_high": "0.3"}},
         ["labels.label_low = 0.7 is above labels.label_high = 0.3", "reversed", "Swap"]),
        ({"labels": {"label_low": "0.5", "label_high": "0.5"}},
         ["labels.label_low and labels.label_high are both 0.5", "zero width",
          "lower label_low or raise label_high"]),
        ({"labels": {"v_slip": ".nan"}}, ["labels.v_slip = nan"]),
        ({"labels": {"horizon_s": ".inf"}}, ["labels.horizon_s = inf"]),
        ({"synthesis": {"annealing": {"temperature_start": "1.0", "temperature_end": "1000.0"}}},
         ["temperature_start", "temperature_end"]),
        ({"synthesis": {"pregrasp": {"standoff": ["0.10", "0.06"]}}},
         ["synthesis.pregrasp.standoff"]),
        ({"train": {"seeds": ["42", "42"]}}, ["train.seeds", "[42]"]),
        ({"splits": {"seeds": ["1", "2", "1"]}}, ["splits.seeds"]),
        ({"sweep": {"windows_s": ["0.01", "0.0101"]}}, ["sweep.windows_s", "10 ms"]),
        ({"sweep": {"windows_s": ["0.0004", "0.01"]}}, ["sweep.windows_s", "millisecond"]),
        ({"tune": {"window_s": "0.8"}}, ["tune.window_s", "sweep.windows_s"]),
        ({"splits": {"window_s": "0.6"}}, ["splits.window_s", "sweep.windows_s"]),
        ({"tune": {"space": {"common": {"dropout": {"low": "0.5", "high": "0.1"}}}}},
         ["tune.space.common.dropout"]),
        ({"only_objects": "014_lemon"}, ["only_objects", "[014_lemon]"]),
        ({"creep_free": {"enabled": "true", "sweep_windows_s": ["0.02"]}},
         ["creep_free.sweep_windows_s", "[0.02]"]),
        ({"monitor": {"window_s": "0.03"}}, ["monitor.window_s = 0.03", "sweep.windows_s"]),
        ({"monitor": {"stride": "0"}}, ["monitor.stride"]),
        ({"replay": {"ramp": {"path": "stop"}}}, ["replay.ramp.path"]),
        ({"replay": {"ramp": {"hold_fraction": "1.5"}}}, ["replay.ramp.hold_fraction"]),
        ({"replay": {"stop_after_loss_s": "0.05"}},
         ["replay.stop_after_loss_s = 0.05", "labels.contact_loss_s = 0.1"]),
        ({"replay": {"deep_stop": {"depth": "-0.005"}}},
         ["replay.deep_stop.depth = -0.005", "penetration_reject = -0.008"]),
        ({"labels": {"settle": {"search_s": "4.0", "penetration_reject_s": "2.0"}}},
         ["replay.deep_stop.seconds = 1.0", "replay.deep_stop.after_s = 3.0", "search_s = 4.0",
          "enabled: false"]),
        ({"replay": {"deep_stop": {"depth": "0.001"}}}, ["replay.deep_stop.depth"]),
        ({"closed_loop": {"enabled": "true"}},
         ["closed_loop.protocols = ['reference', 'creep_free'] names creep_free",
          "creep_free.enabled is false",
          "set creep_free.enabled=true, or closed_loop.protocols=[reference]",
          "--config 'creep_free={enabled: true}'",
          "--config 'closed_loop={enabled: true, protocols: [reference]}'"]),
        ({"closed_loop": {"enabled": "true", "protocols": ["reference"], "window_s": "0.03"}},
         ["closed_loop.window_s = 0.03 s is not a sweep window", "sweep.windows_s"]),
        ({"profile": "closed_loop", "creep_free": {"sweep_windows_s": ["0.05"]},
          "monitor": {"window_s": "0.05"}},
         ["closed_loop.window_s = 0.01 s is not among creep_free.sweep_windows_s ([0.05])"]),
    ],
)  # fmt: skip
def test_bad_values_fail_at_load_time_naming_the_field(override, named):
    with pytest.raises(ConfigError) as err:
        load_config(CONFIG_DIR, SCHEMA, override, check_files=False)
    for text in named:
        assert text in str(err.value)
    assert "narrow" not in str(err.value)  # the old, backwards advice for an empty label band


def test_closed_loop_protocols_with_their_monitors_pass():
    """The closed loop passes with its benchmark on, or under the reference protocol alone, and
    a window is not needed by policies without a monitor."""
    for override in (
        {"closed_loop": {"enabled": "true"}, "creep_free": {"enabled": "true"}},
        {"closed_loop": {"enabled": "true", "protocols": ["reference"]}},
        {"closed_loop": {"enabled": "true", "protocols": ["reference"], "window_s": "0.03",
                         "policies": ["none", "always", "oracle", "pick"],
                         "sweep": {"policies": ["pick"]}}},
    ):  # fmt: skip
        load_config(CONFIG_DIR, SCHEMA, override, check_files=False)


SECRET = "s3cret-Pa55"


@pytest.mark.parametrize(
    ("url", "without"),
    [
        (f"postgresql://graspstab:{SECRET}@db.example.org:5432/graspstab",
         "postgresql://graspstab@db.example.org:5432/graspstab"),
        (f"postgresql+psycopg2://graspstab:{SECRET}@db/graspstab_{{model}}",
         "postgresql+psycopg2://graspstab@db/graspstab_{model}"),
        (f"postgresql://graspstab:p@{SECRET}@db/graspstab", "postgresql://graspstab@db/graspstab"),
        (f"postgresql://graspstab@db/graspstab?password={SECRET}&sslmode=require",
         "postgresql://graspstab@db/graspstab?sslmode=require"),
    ],
)  # fmt: skip
def test_storage_url_with_a_password_is_refused_masked(url, without):
    """A password in tune.storage, from any source, stops the load: the URL is shown masked,
    with the URL to give instead and where libpq reads the password."""
    assert url_password(url) is not None and strip_password(url) == without
    for given in ({"tune": {"storage": url}}, {"overrides": [f"tune.storage='{url}'"]}):
        with pytest.raises(ConfigError) as err:
            load_config(CONFIG_DIR, SCHEMA, given, check_files=False)
        msg = str(err.value)
        assert SECRET not in msg, msg
        assert msg.startswith("tune.storage = ") and "***" in msg and "holds a password" in msg
        assert f"Give the URL without it, {without}, and the password where libpq" in msg
        assert "~/.pgpass" in msg and "PGPASSWORD" in msg


@pytest.mark.parametrize(
    "url",
    [None, "postgresql://graspstab@db.example.org:5432/graspstab_{model}",
     "sqlite:////shared/studies/study@2.sqlite", "postgresql://graspstab:@db/graspstab"],
)  # fmt: skip
def test_storage_url_without_a_password_passes(url):
    cfg = load_config(CONFIG_DIR, SCHEMA, {"tune": {"storage": url}}, check_files=False)
    assert cfg["tune"]["storage"] == url


def test_no_configuration_message_echoes_a_password():
    """Every ConfigError masks URL passwords, also where a message quotes the --config values."""
    url = f"postgresql://graspstab:{SECRET}@db/graspstab"
    with pytest.raises(ConfigError) as err:
        _compose({"tune": {"storage": url, "trails": "3"}})
    assert "trails" in str(err.value) and SECRET not in str(err.value)
    with pytest.raises(ConfigError) as err:  # an unresolvable value: the values are quoted
        _compose({"tune": {"storage": url}, "seed": "${oc.env:GRASPSTAB_NO_SUCH_VARIABLE}"})
    assert "'storage': 'postgresql://graspstab:***@db/graspstab'" in str(err.value)
    assert SECRET not in str(err.value)
    assert mask_text(f"values {{'storage': '{url}'}}") == (
        "values {'storage': 'postgresql://graspstab:***@db/graspstab'}"
    )
    assert SECRET not in str(ConfigError(f"x {url}?password={SECRET} y"))


def test_relation_checks_accept_the_profiles():
    for profile in ("quick", "study", "thesis"):
        load_config(CONFIG_DIR, SCHEMA, {"profile": profile}, check_files=False)
    # a labelling rule the depth stop would cut passes once the stop is off (full replays)
    load_config(CONFIG_DIR, SCHEMA, {"labels": {"settle": {"search_s": "4.0"}},
                                     "replay": {"deep_stop": {"enabled": "false"}}},
                check_files=False)  # fmt: skip


def test_duplicate_object_id_names_the_file_and_the_fix(tmp_path):
    import shutil

    tree = tmp_path / "config"
    shutil.copytree(CONFIG_DIR, tree)
    path = tree / "objects" / "ycb12.yaml"
    path.write_text(path.read_text().replace(
        "items:\n", "items:\n  014_lemon:\n    split: train\n    mass: 0.029\n", 1))  # fmt: skip
    with pytest.raises(ConfigError) as err:
        compose_config(tree, [])
    msg = str(err.value)
    assert "ycb12.yaml" in msg and "014_lemon" in msg and "appears twice" in msg


def test_non_obj_mesh_is_refused_at_load_time(default_cfg, tmp_path):
    stl = tmp_path / "lemon.stl"
    stl.write_bytes(b"solid lemon\nendsolid lemon\n")
    bad = _with_entry(default_cfg, "014_lemon", mesh=str(stl))
    with pytest.raises(ConfigError) as err:
        validate_config(bad, SCHEMA)
    msg = str(err.value)
    assert "014_lemon" in msg and "'mesh'" in msg and str(stl) in msg and "OBJ" in msg


def test_crossval_kfold_alone_turns_on_its_creep_free_protocol():
    """`--config crossval=kfold` (README) runs both protocols, so it turns the creep-free benchmark
    on (config/crossval/kfold.yaml is global); turning it off names both fixes."""
    cfg = load_config(CONFIG_DIR, SCHEMA, {"crossval": "kfold"}, check_files=False)
    default = load_config(CONFIG_DIR, SCHEMA, {}, check_files=False)
    assert cfg["crossval"]["enabled"] and cfg["creep_free"]["enabled"]
    assert cfg["crossval"]["protocols"] == ["reference", "creep_free"]
    assert cfg["crossval"]["k"] == default["crossval"]["k"]  # the default option's settings
    assert {k: v for k, v in cfg["creep_free"].items() if k != "enabled"} == {
        k: v for k, v in default["creep_free"].items() if k != "enabled"
    }
    off = {"crossval": "kfold", "creep_free": {"enabled": "false"}}
    with pytest.raises(ConfigError) as err:
        load_config(CONFIG_DIR, SCHEMA, off, check_files=False)
    assert "creep_free={enabled: true}" in str(err.value)
    assert "crossval.protocols=[reference]" in str(err.value)
    alone = {**off, "overrides": ["crossval.protocols=[reference]"]}
    alone = load_config(CONFIG_DIR, SCHEMA, alone, check_files=False)
    assert alone["crossval"]["protocols"] == ["reference"] and not alone["creep_free"]["enabled"]
