"""The Optuna storage of a tuning study: opened once with a readable error, and the trials still
in flight on a database that several workers share.

A wrong ``tune.storage`` (malformed URL, missing driver, unreachable server, bad password, missing
database) ends the job with one paragraph that names the URL with its password hidden and the fix,
not a SQLAlchemy traceback. Workers sharing a study tell live trials from dead ones by Optuna's
heartbeats; :func:`live_trials` reads them so a worker neither starts a trial that another worker's
running trial makes surplus nor returns before those trials have finished.
"""

from __future__ import annotations

import warnings

import optuna
import sqlalchemy
from optuna.storages._rdb import models
from sqlalchemy.engine import make_url

from graspstab.common.errors import GraspstabError

# Heartbeats of a shared study: a trial is live while its worker has beaten within GRACE_S.
HEARTBEAT_S = 60
GRACE_S = 180
DRIVER_HINT = "pip install -e '.[cluster]' (psycopg2-binary, the driver of postgresql:// URLs)"


class StorageError(SystemExit, GraspstabError):
    """The study's storage cannot be opened. A SystemExit, so a direct caller of
    :func:`graspstab.learning.tune_model.tune_model` ends with this one paragraph on stderr, exit
    status 1 and no traceback; a graspstab error too, so the workflow job reports it in its log
    like the others (:func:`graspstab.common.jobs.job`). The message names the URL without its
    password."""


def _userinfo(url: str) -> tuple[str, str, str] | None:
    """An unparsable URL cut around its password (text before, password, text from the ``@``),
    or None when it has none: the userinfo runs from the last ``//`` before the last ``@``."""
    at = url.rfind("@")
    start = url.rfind("//", 0, at) + 2 if url.rfind("//", 0, at) >= 0 else 0
    if at < 0 or ":" not in url[start:at]:
        return None
    user, password = url[start:at].split(":", 1)
    return url[:start] + user + ":", password, url[at:]


def hide_password(url: str) -> str:
    """``url`` with its password replaced by ``***``, parsed or not (an unparsable URL may still
    hold a password)."""
    try:
        return make_url(url).render_as_string(hide_password=True)
    except (sqlalchemy.exc.ArgumentError, ValueError):
        parts = _userinfo(url)
        return f"{parts[0]}***{parts[2]}" if parts else url


def _password(url: str) -> str | None:
    """The URL's password, parsed or not, to scrub it from a driver's message."""
    try:
        return make_url(url).password
    except (sqlalchemy.exc.ArgumentError, ValueError):
        parts = _userinfo(url)
        return parts[1] if parts else None


def _reason(exc: BaseException, url: str) -> str:
    """The driver's own words as one sentence or more on one line (SQLAlchemy's wrapper and help
    link dropped), without the password."""
    lines = [line.strip() for line in str(getattr(exc, "orig", None) or exc).splitlines()]
    text = " ".join(line if line[-1] in ".?!" else f"{line}." for line in lines if line)
    secret = _password(url)
    return text.replace(secret, "***") if secret else text


def _missing_module(exc: BaseException) -> str | None:
    """The module whose import failed somewhere in ``exc``'s chain (Optuna rewraps it)."""
    while exc is not None:
        if isinstance(exc, ModuleNotFoundError) and exc.name:
            return exc.name
        exc = exc.__cause__ or exc.__context__
    return None


def open_storage(url: str, *, shared: bool) -> optuna.storages.RDBStorage:
    """Connect to ``url`` (creating Optuna's tables), heartbeats on when ``shared``; raise
    :class:`StorageError` naming the URL, the cause and the fix when that fails."""
    shown = hide_password(url)
    where = "tune.storage" if shared else "the study's own SQLite file (tune.storage null)"
    prefix = f"graspstab tuning storage error: {where} {shown}"
    try:
        make_url(url)
    except (sqlalchemy.exc.ArgumentError, ValueError) as exc:
        raise StorageError(
            f"{prefix} is not a database URL: {_reason(exc, url)} Give one like "
            "postgresql://user:password@host:5432/database, or null for SQLite beside the results."
        ) from None
    heartbeat = {"heartbeat_interval": HEARTBEAT_S, "grace_period": GRACE_S} if shared else {}
    try:
        with warnings.catch_warnings():  # heartbeats are experimental in Optuna, and wanted here
            warnings.simplefilter("ignore", optuna.exceptions.ExperimentalWarning)
            return optuna.storages.RDBStorage(url, **heartbeat)
    except sqlalchemy.exc.NoSuchModuleError as exc:
        raise StorageError(
            f"{prefix} names a database kind SQLAlchemy does not know: {_reason(exc, url)} "
            "Use postgresql://, mysql:// or sqlite:///, or null for SQLite beside the results."
        ) from None
    except ImportError as exc:
        module = _missing_module(exc) or "its database driver"
        raise StorageError(
            f"{prefix} needs the Python module {module!r}, which is not installed: {DRIVER_HINT}, "
            "or the driver your database's SQLAlchemy dialect names."
        ) from None
    except sqlalchemy.exc.SQLAlchemyError as exc:
        raise StorageError(
            f"{prefix} cannot be opened: {_reason(exc, url)} Check that the server runs and "
            "accepts connections from this host, that the user, password and database name are "
            "right, and that the database exists (createdb); or set tune.storage to null for "
            "SQLite beside the results."
        ) from None


def live_trials(storage: optuna.storages.RDBStorage, study_id: int) -> set[int]:
    """Numbers of the study's RUNNING trials whose worker is alive: one that has beaten within
    the grace period. A RUNNING trial without a heartbeat (a client without heartbeats) is not
    counted: nothing says it will finish. Optuna has no public query for this, so its heartbeat
    table is read directly, as its own stale-trial check does."""
    if storage.heartbeat_interval is None:
        return set()
    grace = storage.grace_period or 2 * storage.heartbeat_interval
    session = storage.scoped_session()
    try:
        now = session.execute(sqlalchemy.func.now()).scalar_one().replace(tzinfo=None)
        rows = (
            session.query(models.TrialModel.number, models.TrialHeartbeatModel.heartbeat)
            .join(models.TrialHeartbeatModel,
                  models.TrialHeartbeatModel.trial_id == models.TrialModel.trial_id)
            .filter(models.TrialModel.study_id == study_id,
                    models.TrialModel.state == optuna.trial.TrialState.RUNNING)
            .all()
        )  # fmt: skip
    finally:
        session.close()
    return {number for number, beat in rows if (now - beat).total_seconds() <= grace}
