"""A throwaway PostgreSQL server from Debian's ``postgresql`` package, for the tests marked
``servers``: its own data directory in a temporary folder, a free TCP port on 127.0.0.1 and a
password-protected user, stopped and removed afterwards.

The server refuses to run as root, so under root it runs as the ``postgres`` system user (the
package creates it). A missing server binary fails the test with the command that installs it:
these tests are skipped only on request (``-m 'not servers'``), never because a package is absent.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

INSTALL = "apt-get install -y postgresql"
PG_ROOT = Path("/usr/lib/postgresql")  # Debian's versioned server trees, <version>/bin
USER = "graspstab"
PASSWORD = "s3cret-Pa55"  # a real password, so every test can check that it is never shown
DATABASE = "graspstab"


def server_bin() -> Path:
    """The newest Debian PostgreSQL ``bin`` folder, or fail saying how to install one."""
    found = sorted(
        PG_ROOT.glob("*/bin/initdb"),
        key=lambda p: int(p.parent.parent.name) if p.parent.parent.name.isdigit() else 0,
    )
    if not found:
        pytest.fail(
            f"no PostgreSQL server binaries ({PG_ROOT}/<version>/bin/initdb): install "
            f"Debian's server with `{INSTALL}`, or deselect these tests with -m 'not servers'",
            pytrace=False,
        )
    return found[-1].parent


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@dataclass(frozen=True)
class Postgres:
    """A running server: where it listens and who may log in."""

    bindir: Path
    root: Path
    port: int
    run_as: list[str]

    def url(self, database: str = DATABASE, *, password: str = PASSWORD) -> str:
        """The SQLAlchemy URL of ``database`` for the test user."""
        return f"postgresql://{USER}:{password}@127.0.0.1:{self.port}/{database}"

    def createdb(self, name: str) -> str:
        """Create database ``name`` and return its URL."""
        self._run("createdb", "-h", "127.0.0.1", "-p", str(self.port), "-U", USER, name)
        return self.url(name)

    def _run(self, tool: str, *args: str) -> str:
        env = ["env", f"PGPASSWORD={PASSWORD}", "LC_ALL=C"]
        done = subprocess.run([*self.run_as, *env, str(self.bindir / tool), *args],
                              capture_output=True, text=True, cwd=self.root)  # fmt: skip
        if done.returncode:
            log = self.root / "server.log"
            tail = log.read_text()[-3000:] if log.exists() else "(no server log)"
            raise RuntimeError(f"{tool} {' '.join(args)} failed ({done.returncode}):\n"
                               f"{done.stdout}{done.stderr}\nserver log:\n{tail}")  # fmt: skip
        return done.stdout


@contextlib.contextmanager
def postgres_server() -> Iterator[Postgres]:
    """Start a server with user ``graspstab`` (password :data:`PASSWORD`, scram-sha-256 over
    TCP) owning database ``graspstab``; stop it and remove its folder on the way out."""
    bindir = server_bin()
    root = Path(tempfile.mkdtemp(prefix="graspstab-pg-"))
    run_as: list[str] = []
    if os.geteuid() == 0:
        if not shutil.which("runuser"):
            pytest.fail("running as root needs runuser (util-linux) to start PostgreSQL as the "
                        "postgres user", pytrace=False)  # fmt: skip
        try:
            shutil.chown(root, user="postgres")
        except LookupError:
            pytest.fail(f"no postgres system user: install Debian's server with `{INSTALL}`",
                        pytrace=False)  # fmt: skip
        run_as = ["runuser", "-u", "postgres", "--"]
    root.chmod(0o700)
    server = Postgres(bindir, root, free_port(), run_as)
    try:
        (root / "pwfile").write_text(PASSWORD + "\n")
        if run_as:
            shutil.chown(root / "pwfile", user="postgres")
        server._run("initdb", "-D", str(root / "data"), "-U", USER, "--pwfile",
                    str(root / "pwfile"), "--auth", "scram-sha-256", "-E", "UTF8",
                    "--locale", "C")  # fmt: skip
        options = f"-p {server.port} -k {root} -c listen_addresses=127.0.0.1 -c fsync=off"
        server._run("pg_ctl", "-D", str(root / "data"), "-o", options, "-l",
                    str(root / "server.log"), "-w", "-t", "60", "start")  # fmt: skip
        server.createdb(DATABASE)
        yield server
    finally:
        try:
            if (root / "data" / "postmaster.pid").exists():  # started, even if start timed out
                server._run("pg_ctl", "-D", str(root / "data"), "-m", "fast", "-w", "stop")
        finally:
            shutil.rmtree(root, ignore_errors=True)
