"""Tuning against a real PostgreSQL server (Debian's ``postgresql``, started per session by
tests/servers/postgres.py): two concurrent workers on one study, and the message a wrong or
unreachable ``tune.storage`` gives.

Every URL here is password-free, as the config validator demands (docs/cluster.md): libpq reads
the password from a pgpass file in this process (``PGPASSFILE``, as ``~/.pgpass`` would be) and
from ``PGPASSWORD`` in the worker processes, which are given no pgpass file, so both ways the
documentation names are proven against the server.

Every test here is marked ``servers``: ``-m 'not servers'`` deselects them; nothing skips them
silently (no server binary is a failure that names the package to install).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import optuna
import pytest
from conftest import REPO
from servers import postgres as pg_server
from servers.postgres import DATABASE, PASSWORD, USER, Postgres, free_port, postgres_server
from test_learning_train import LSTM, TRAIN, TUNE, write_dataset

from graspstab.learning import tune_model as tm
from graspstab.learning.storage import hide_password

pytestmark = pytest.mark.servers

TRIALS = 6
DONE = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)
# max_epochs below the pruner's warm-up: no trial is pruned, so every value is a full training's.
SETTINGS: dict[str, Any] = {"base": LSTM, "train": {**TRAIN, "max_epochs": 3}}
STARTUP_S = 300  # a worker's import and study, on a loaded machine
RUN_S = 600
LOG_RECORD = re.compile(r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d,\d+ [A-Z]+ ")  # setup_logging's format

# One tuning worker, as a process of its own: imports, says it is ready, waits for the go file
# (so two workers really start together), then runs the project's tune_model.
WORKER = """
import json, sys, time
from pathlib import Path
from graspstab.learning.tune_model import tune_model
a = json.loads(Path(sys.argv[1]).read_text())
Path(a["ready"]).touch()
while not Path(a["go"]).exists():
    time.sleep(0.02)
tune_model(a["dataset"], a["base"], a["train"], a["tune"], a["best"], a["trials"],
           default_storage=a["default_storage"], log_file=a["log"])
"""

# The rule's own script (workflow/scripts/tune_model.py) in its own Python process, as Snakemake
# runs a script job, with a stand-in for the ``snakemake`` object it is given; "block" makes the
# named modules unimportable (a missing driver).
SCRIPT = """
import json, runpy, sys
from pathlib import Path
from types import SimpleNamespace as NS
a = json.loads(Path(sys.argv[1]).read_text())
for name in a["block"]:
    sys.modules[name] = None
snakemake = NS(
    input=NS(index=str(Path(a["dataset"]) / "index.parquet")),
    params=NS(base=a["base"], train=a["train"], tune=a["tune"],
              default_storage=a["default_storage"]),
    output=NS(best=a["best"], trials=a["trials"]), threads=1, log=[a["log"]],
    config={"cache": {"enabled": False}}, rule="tune_model", wildcards={},
)
runpy.run_path(a["script"], init_globals={"snakemake": snakemake}, run_name="__main__")
"""


@pytest.fixture(scope="session")
def postgres() -> Iterator[Postgres]:
    """One throwaway server for the session, stopped and removed in a finally."""
    with postgres_server() as server:
        yield server


@pytest.fixture(scope="module", autouse=True)
def pgpass(postgres: Postgres, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The test user's password in a pgpass file (mode 600) that libpq reads in this process,
    with no PGPASSWORD set: the in-process connections prove the pgpass way."""
    path = tmp_path_factory.mktemp("pgpass") / "pgpass"
    path.write_text(f"127.0.0.1:{postgres.port}:*:{USER}:{PASSWORD}\n")
    path.chmod(0o600)
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PGPASSFILE", str(path))
        mp.delenv("PGPASSWORD", raising=False)
        yield path


def _url(postgres: Postgres, database: str = DATABASE) -> str:
    """The password-free URL of ``database`` for the test user."""
    return f"postgresql://{USER}@127.0.0.1:{postgres.port}/{database}"


def _createdb(postgres: Postgres, name: str) -> str:
    """Create database ``name``; its password-free URL."""
    postgres.createdb(name)
    return _url(postgres, name)


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Planted windows with label noise, so the trials' validation AUPRCs differ."""
    root = tmp_path_factory.mktemp("pg_dataset")
    return write_dataset(root, {"train": 40, "val": 30, "test": 10}, seed=3)


def _args(root: Path, dataset: Path, url: str | None, **extra: Any) -> dict[str, Any]:
    root.mkdir(parents=True, exist_ok=True)
    return {
        **SETTINGS,
        "dataset": str(dataset),
        "tune": {**TUNE, "trials": TRIALS, "storage": url},
        "best": str(root / "best.json"),
        "trials": str(root / "trials.parquet"),
        "default_storage": str(root / "study.sqlite"),
        "log": str(root / "tune.log"),
        "ready": str(root / "ready"),
        **extra,
    }


def _start(
    code: str, args: dict[str, Any], root: Path, password: str = PASSWORD
) -> subprocess.Popen[str]:
    """A worker process whose only password is ``PGPASSWORD`` (no pgpass file)."""
    (root / "args.json").write_text(json.dumps(args))
    env = {k: v for k, v in os.environ.items() if k != "PGPASSFILE"}
    env.update(PYTHONPATH=str(REPO / "src"), PGPASSWORD=password,
               PGPASSFILE=str(root / "no-pgpass"))  # fmt: skip
    cmd = [sys.executable, "-c", code, str(root / "args.json")]
    return subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)  # fmt: skip


def _tune_workers(roots: list[Path], dataset: Path, url: str) -> list[dict[str, Any]]:
    """Run one worker per folder in ``roots`` on one study, started together; their records."""
    go = roots[0].parent / f"go-{roots[0].name}"
    procs = [_start(WORKER, _args(r, dataset, url, go=str(go)), r) for r in roots]
    try:
        deadline = time.monotonic() + STARTUP_S
        while not all((r / "ready").exists() for r in roots):
            assert all(p.poll() is None for p in procs), [p.communicate() for p in procs]
            assert time.monotonic() < deadline, "the workers did not start"
            time.sleep(0.05)
        go.touch()
        outs = [p.communicate(timeout=RUN_S) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for p, (_, err) in zip(procs, outs, strict=True):
        assert p.returncode == 0, err[-4000:]
    return [json.loads((r / "best.json").read_text()) for r in roots]


def test_libpq_reads_the_password_outside_the_url(
    postgres: Postgres, pgpass: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The password-free URL connects through the pgpass file, and through PGPASSWORD alone; with
    neither, the server refuses it (so the other tests' connections really used them)."""
    import sqlalchemy

    def connect() -> None:
        engine = sqlalchemy.create_engine(_url(postgres))
        try:
            with engine.connect() as conn:
                assert conn.execute(sqlalchemy.text("select current_user")).scalar() == USER
        finally:
            engine.dispose()

    connect()  # the pgpass file
    monkeypatch.setenv("PGPASSFILE", str(tmp_path / "none"))
    with pytest.raises(sqlalchemy.exc.OperationalError, match="password"):
        connect()
    monkeypatch.setenv("PGPASSWORD", PASSWORD)
    connect()


def _key(params: dict[str, Any]) -> str:
    return json.dumps(params, sort_keys=True)


def test_two_workers_share_one_study(postgres: Postgres, dataset: Path, tmp_path: Path) -> None:
    """Two worker processes tune one study in one database: no trial is lost, duplicated or left
    running, and the result is the one-worker run's.

    Which promise makes the comparison well-defined: Optuna reproduces a seeded sampler's trials
    only for a sequential run (its FAQ on reproducibility); with parallel workers the TPE
    proposals depend on timing. So the one-worker run is the sequential seeded TPE study, and the
    two-worker study is given that run's parameter sets as enqueued trials
    (``study.enqueue_trial``): a WAITING trial is popped by exactly one worker (the RDB storage's
    row-locked RUNNING transition) and evaluated with exactly its fixed parameters. Training is
    seeded per trial (``tune.seed``, one thread), so each set gives the same value whichever
    worker runs it, and both studies must have the same best parameters and value.
    """
    ref_url = _createdb(postgres, "graspstab_one")
    assert PASSWORD not in ref_url
    [ref_record] = _tune_workers([tmp_path / "one"], dataset, ref_url)
    name = ref_record["study_name"]
    ref = optuna.load_study(study_name=name, storage=ref_url)
    ref_done = ref.get_trials(states=DONE)
    assert len(ref_done) == TRIALS == len(ref.trials)
    values = {_key(t.params): t.value for t in ref_done}
    assert len(values) == TRIALS  # the seeded TPE run proposed six different sets
    assert ref_record["best_value"] == ref.best_value == max(values.values())
    assert sorted(values.values()).count(ref.best_value) == 1, "a tie would leave no single best"

    url = _createdb(postgres, "graspstab_two")
    study = optuna.create_study(study_name=name, storage=url, direction="maximize")
    for t in sorted(ref_done, key=lambda t: t.number):
        study.enqueue_trial(t.params)
    records = _tune_workers([tmp_path / "w1", tmp_path / "w2"], dataset, url)

    trials = optuna.load_study(study_name=name, storage=url).get_trials()
    done = [t for t in trials if t.state in DONE]
    assert len(done) == TRIALS, [(t.number, t.state.name) for t in trials]
    assert sorted(t.number for t in trials) == list(range(len(trials)))  # unique, contiguous
    left = [t.state.name for t in trials if t.state not in DONE]
    assert set(left) <= {"FAIL"}, left  # none RUNNING or WAITING; a surplus trial is failed unrun
    assert all(not t.params for t in trials if t.state not in DONE)
    assert sorted(_key(t.params) for t in done) == sorted(values)  # each set once, none lost
    for t in done:
        assert t.value == values[_key(t.params)], t.params
    # Both workers ran trials, at the same time: a worker runs its trials one after another.
    spans = sorted((t.datetime_start, t.datetime_complete) for t in done)
    assert any(b_start < a_end for (_, a_end), (b_start, _) in zip(spans, spans[1:], strict=False))
    for record in records:  # each worker returned only once the study held all six
        assert record["study_name"] == name
        assert record["trials"]["complete"] + record["trials"]["pruned"] == TRIALS
        assert record["spec"] == ref_record["spec"]  # the best trial's parameters
        assert record["best_value"] == ref_record["best_value"]
        assert record["trials"]["waiting"] == 0
        stored = record["params"]["tune"]["storage"]
        assert PASSWORD not in json.dumps(record) and stored == url


WRONG = "wrong-Pa55"


def _bad_urls(postgres: Postgres) -> dict[str, tuple[str, str, list[str], str]]:
    """Case: (URL, what the message must say besides the URL, modules to block, the worker's
    PGPASSWORD)."""
    host = f"127.0.0.1:{postgres.port}"
    return {
        "unreachable": (f"postgresql://{USER}@127.0.0.1:{free_port()}/{DATABASE}",
                        "Connection refused", [], PASSWORD),
        "bad_password": (_url(postgres), f'password authentication failed for user "{USER}"',
                         [], WRONG),
        "no_database": (_url(postgres, "no_such_db"), 'database "no_such_db" does not exist', [],
                        PASSWORD),
        "malformed_port": (f"postgresql://{USER}@{host}x/{DATABASE}", "is not a database URL",
                           [], PASSWORD),
        "malformed": (f"postgresql//{USER}@{host}/{DATABASE}", "is not a database URL", [],
                      PASSWORD),
        "unknown_kind": (f"postgres://{USER}@{host}/{DATABASE}",
                         "database kind SQLAlchemy does not know", [], PASSWORD),
        "no_driver": (_url(postgres), "'psycopg2', which is not installed: pip install -e "
                      "'.[cluster]' (psycopg2-binary", ["psycopg2"], PASSWORD),
    }  # fmt: skip


CASES = ["unreachable", "bad_password", "no_database", "malformed_port", "malformed",
         "unknown_kind", "no_driver"]  # fmt: skip


def test_bad_storage_is_one_message(postgres: Postgres, dataset: Path, tmp_path: Path) -> None:
    """An unreachable server, a wrong password (PGPASSWORD) or a wrong URL (database, syntax,
    kind, driver): the rule's script exits non-zero with one line in its log naming the URL, the
    driver's reason and the fix, no traceback and no password, and writes no output."""
    cases = _bad_urls(postgres)
    assert sorted(cases) == sorted(CASES)
    script = str(REPO / "workflow" / "scripts" / "tune_model.py")
    procs = {}
    for case in CASES:  # all at once: each is an import of torch and one failed connection
        url, _, block, password = cases[case]
        root = tmp_path / case
        args = _args(root, dataset, url, script=script, block=block)
        procs[case] = _start(SCRIPT, args, root, password=password)
    for case, proc in procs.items():
        url, reason, _, _ = cases[case]
        out, err = proc.communicate(timeout=STARTUP_S)
        shown = hide_password(url)
        assert shown == url and PASSWORD not in url  # nothing to hide: no password in the URL
        assert proc.returncode == 1, (case, err)
        log = (tmp_path / case / "tune.log").read_text()
        assert "Traceback" not in err + out + log, (case, err, log)
        assert PASSWORD not in err + out + log and WRONG not in err + out + log, case
        # the message is the last record of the job's log, one line (Snakemake prints a failed
        # job's log under its error block: graspstab.common.jobs); stderr has the other records
        assert [line for line in err.splitlines() if line and not LOG_RECORD.match(line)] == []
        [record] = [line for line in log.splitlines() if "ERROR graspstab.job: " in line]
        assert log.rstrip().endswith(record) and LOG_RECORD.match(record), (case, log)
        message = record.split("ERROR graspstab.job: tune_model failed: ", 1)[1]
        assert message.startswith(f"graspstab tuning storage error: tune.storage {shown} "), case
        assert reason in message, (case, message)
        assert not (tmp_path / case / "best.json").exists()


def test_surplus_trial_yields_unrun(
    postgres: Postgres, dataset: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Two workers that ask at the same moment may both start the trial that makes ``trials``:
    the one numbered later sees the other live, is failed before training (no parameters) and
    stops, and the worker then runs a trial only once nothing live remains."""
    url = _createdb(postgres, "graspstab_surplus")
    args = _args(tmp_path, dataset, url)
    run = {"dataset_dir": dataset, "base_spec": args["base"], "train": args["train"],
           "out_best": args["best"], "out_trials": args["trials"],
           "default_storage": args["default_storage"]}  # fmt: skip
    name = tm.tune_model(**run, tune={**args["tune"], "trials": 1})["study_name"]
    other = optuna.load_study(study_name=name, storage=url).ask()  # the trial asked at once
    armed = [True]

    def live(storage: optuna.storages.RDBStorage, study_id: int) -> set[int]:
        """``other`` is live exactly when the worker's own new trial checks it (the race)."""
        running = {t.number for t in optuna.load_study(study_name=name, storage=url).trials
                   if t.state == optuna.trial.TrialState.RUNNING}  # fmt: skip
        if armed[0] and running - {other.number}:
            armed[0] = False
            return {other.number}
        return set()

    monkeypatch.setattr(tm, "live_trials", live)
    record = tm.tune_model(**run, tune={**args["tune"], "trials": 2})
    assert not armed[0]  # the race was staged
    trials = optuna.load_study(study_name=name, storage=url).trials
    states = [(t.number, t.state.name) for t in trials]
    assert states == [(0, "COMPLETE"), (1, "RUNNING"), (2, "FAIL"), (3, "COMPLETE")]
    assert not trials[2].params and trials[3].params and trials[0].params
    assert record["trials"]["complete"] == 2 and record["trials"]["fail"] == 1


def test_missing_server_fails_with_install_hint(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """No server binaries is a failure (not a skip) that says how to install them."""
    monkeypatch.setattr(pg_server, "PG_ROOT", tmp_path)
    with pytest.raises(pytest.fail.Exception, match=r"apt-get install -y postgresql"):
        pg_server.server_bin()
    (tmp_path / "15" / "bin").mkdir(parents=True)
    (tmp_path / "15" / "bin" / "initdb").touch()
    (tmp_path / "9" / "bin").mkdir(parents=True)
    (tmp_path / "9" / "bin" / "initdb").touch()
    assert pg_server.server_bin() == tmp_path / "15" / "bin"  # the newest, numerically
