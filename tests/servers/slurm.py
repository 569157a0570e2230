"""A throwaway single-node SLURM cluster on this machine, from Debian's packages (Debian 12: SLURM
22.05, munge 0.5, MariaDB 10.11), for the tests marked ``servers``.

Everything lives in one folder (keys, configuration, state, spool, logs, the accounting
database); nothing under /etc, /run or /var is read or written, and the ports are free ones
picked at start. The daemons, in start order:

* ``munged``: SLURM's authentication, with a fresh key and its own socket (``AuthInfo=socket=``);
* ``mariadbd`` and ``slurmdbd``: the accounting store. SLURM 22.05's ``sacct`` reads job records
  only from slurmdbd ("Slurm accounting storage is disabled" under
  ``accounting_storage/none``), slurmdbd stores only in MySQL/MariaDB, and the Snakemake SLURM
  executor plugin asks ``sacct`` for job states by default. The database server runs
  ``--skip-grant-tables`` on 127.0.0.1: a test cluster of one user, no passwords to keep;
* ``slurmctld`` and ``slurmd``: the controller and one node, ``NodeName=<this hostname>`` with
  ``cpus`` CPUs (2 by default) and ``RealMemory`` a little under this machine's memory. No
  cgroups (``proctrack/linuxproc``, ``task/none``): memory is a scheduling figure here, not a
  limit. ``nice`` (19 by default) is the daemons' niceness, which the jobs inherit
  (``PropagatePrioProcess=0``), so a test cluster yields to whatever else the machine is doing.

``SlurmCluster.env`` is the environment for the client commands (``SLURM_CONF``) and for
whatever submits jobs (they are submitted with ``--export=ALL``); every daemon and every job
started from it carries ``MARKER`` in its environment, which is how ``leftovers`` finds
anything that outlived ``stop``.

    cluster = SlurmCluster(tmp_path / "slurm")
    cluster.start()          # returns once sinfo shows the node idle
    try:
        subprocess.run(["sbatch", "--wrap", "hostname"], env=cluster.env)
    finally:
        cluster.stop()       # cancels the jobs, stops every daemon, raises if one is left

Also a command line for CI or a person: ``python -m tests.servers.slurm start DIR`` (prints the
``export SLURM_CONF=...`` line) and ``python -m tests.servers.slurm stop DIR``.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

# Debian 12's packages for every program used here.
APT_PACKAGES = "slurmctld slurmd slurm-client munge slurmdbd mariadb-server"
APT_HINT = f"apt-get install {APT_PACKAGES}"
BINARIES = {
    "munged": "munge",
    "mariadb-install-db": "mariadb-server",
    "mariadbd": "mariadb-server",
    "slurmdbd": "slurmdbd",
    "slurmctld": "slurmctld",
    "slurmd": "slurmd",
    "sbatch": "slurm-client",
    "sacct": "slurm-client",
    "sacctmgr": "slurm-client",
    "squeue": "slurm-client",
    "sinfo": "slurm-client",
    "scancel": "slurm-client",
    "scontrol": "slurm-client",
}
# Every daemon's and job's environment holds this variable, set to the cluster's folder.
MARKER = "GRASPSTAB_TEST_SLURM"
DAEMONS = ("munged", "mariadbd", "slurmdbd", "slurmctld", "slurmd", "slurmstepd")
CLUSTER_NAME = "graspstab"
PARTITION = "debug"
_SBIN = "/usr/local/sbin:/usr/sbin:/sbin"


class ServerError(RuntimeError):
    """The cluster could not be started or stopped; the message says why."""


class MissingBinaries(ServerError):
    """Programs the cluster needs are not installed; the message names the packages."""


def find_binaries() -> dict[str, str]:
    """Each program's path; MissingBinaries naming the apt-get command if any is missing."""
    path = os.pathsep.join((os.environ.get("PATH", ""), _SBIN))
    found = {name: shutil.which(name, path=path) for name in BINARIES}
    missing = sorted(name for name, where in found.items() if where is None)
    if missing:
        packages = sorted({BINARIES[m] for m in missing})
        raise MissingBinaries(
            f"the SLURM test cluster needs {', '.join(missing)} (Debian packages "
            f"{', '.join(packages)}), not found on PATH or in {_SBIN}: install them with "
            f"`{APT_HINT}`"
        )
    return found  # type: ignore[return-value]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _port_open(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex(("127.0.0.1", port)) == 0


def _memory_mb() -> int:
    for line in Path("/proc/meminfo").read_text().splitlines():
        if line.startswith("MemTotal:"):
            return int(line.split()[1]) // 1024
    raise ServerError("no MemTotal in /proc/meminfo")


def _environ(pid: int) -> dict[str, str]:
    try:
        raw = Path(f"/proc/{pid}/environ").read_bytes()
    except OSError:
        return {}
    pairs = (item.split(b"=", 1) for item in raw.split(b"\0") if b"=" in item)
    return {k.decode(errors="replace"): v.decode(errors="replace") for k, v in pairs}


def _comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return False
    return state != "Z"


class SlurmCluster:
    """One controller, one node, accounting; see the module docstring."""

    def __init__(
        self, root: Path, cpus: int = 2, real_memory_mb: int | None = None, nice: int = 19
    ) -> None:
        self.root = Path(root).resolve()
        self.cpus = cpus
        # a little under the machine's memory (slurmd drains a node configured above it)
        self.real_memory_mb = real_memory_mb or max(1000, _memory_mb() - 2048)
        self.nice = nice
        self.node = socket.gethostname().split(".")[0]
        self.conf = self.root / "etc" / "slurm.conf"
        self.procs: dict[str, subprocess.Popen] = {}
        self.bin: dict[str, str] = {}

    # -- environment and client commands ---------------------------------------------------

    @property
    def env(self) -> dict[str, str]:
        """os.environ with the client commands pointed at this cluster, and the marker; the
        folder of the ``srun`` shim first on PATH (``_write_srun_shim``)."""
        path = os.pathsep.join((str(self.root / "bin"), os.environ.get("PATH", ""), _SBIN))
        return dict(os.environ, SLURM_CONF=str(self.conf), PATH=path, **{MARKER: str(self.root)})

    def client(self, *args: str, check: bool = True, timeout: float = 60) -> str:
        """Run a SLURM client command against this cluster; its stdout."""
        proc = subprocess.run(
            list(args), env=self.env, capture_output=True, text=True, timeout=timeout
        )
        if check and proc.returncode != 0:
            raise ServerError(f"{' '.join(args)} failed ({proc.returncode}): {proc.stderr}")
        return proc.stdout

    def log(self, name: str, tail: int = 3000) -> str:
        path = self.root / "log" / f"{name}.log"
        return path.read_text(errors="replace")[-tail:] if path.is_file() else "(no log)"

    # -- start ------------------------------------------------------------------------------

    def _spawn(self, name: str, *args: str) -> None:
        cmd = ["nice", "-n", str(self.nice), *args]
        with open(self.root / "log" / f"{name}.out", "w") as out:  # the daemon keeps its copy
            self.procs[name] = subprocess.Popen(
                cmd,
                env=self.env,
                stdout=out,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        self._record()

    def _record(self) -> None:
        pids = {name: p.pid for name, p in self.procs.items()}
        (self.root / "pids.json").write_text(json.dumps(pids))

    def _wait(self, what: str, ready, name: str, timeout: float = 60) -> None:
        deadline = time.monotonic() + timeout
        while not ready():
            proc = self.procs.get(name)
            if proc is not None and proc.poll() is not None:
                out = (self.root / "log" / f"{name}.out").read_text(errors="replace")[-3000:]
                raise ServerError(
                    f"{name} exited ({proc.returncode}) before {what}:\n{out}\n{self.log(name)}"
                )
            if time.monotonic() > deadline:
                raise ServerError(f"no {what} after {timeout:.0f} s:\n{self.log(name)}")
            time.sleep(0.2)

    def start(self) -> SlurmCluster:
        """Start every daemon; returns once the node is idle. On failure, stops what started."""
        self.bin = find_binaries()
        for sub in ("bin", "etc", "munge", "log", "run", "state", "spool", "mysql", "tmp"):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        self.root.chmod(0o700)
        self._write_srun_shim()
        try:
            self._start_munge()
            self._start_database()
            self._start_slurm()
        except BaseException:
            self.stop(check=False)
            raise
        return self

    def _write_srun_shim(self) -> None:
        """``bin/srun``: srun with ``SLURM_CONF`` put back when its caller dropped it.

        snakemake-executor-plugin-slurm-jobstep (0.6.1) runs each job as
        ``srun -n1 --cpu-bind=q ...`` from inside the sbatch job, with every ``SLURM_*``
        variable but the job's identity removed from srun's environment, ``SLURM_CONF``
        included. A real cluster's srun then finds its configuration at the default path
        (/etc/slurm/slurm.conf) or from slurmd (configless); this cluster's lives in its own
        folder, which only ``SLURM_CONF`` names, and nothing here writes under /etc. The shim
        stands in for the default path; it changes nothing else about srun."""
        real = shutil.which("srun", path=os.environ.get("PATH", "") + os.pathsep + _SBIN)
        if real is None:
            raise MissingBinaries(f"srun not found (Debian package slurm-client): `{APT_HINT}`")
        shim = self.root / "bin" / "srun"
        shim.write_text(
            f'#!/bin/sh\nexport SLURM_CONF="${{SLURM_CONF:-{self.conf}}}"\nexec {real} "$@"\n'
        )
        shim.chmod(0o755)

    def _start_munge(self) -> None:
        key = self.root / "munge" / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o400)
        self.munge_socket = self.root / "munge" / "munge.socket"
        self._spawn(
            "munged",
            self.bin["munged"],
            "--foreground",
            "--force",
            f"--socket={self.munge_socket}",
            f"--key-file={key}",
            f"--pid-file={self.root / 'run' / 'munged.pid'}",
            f"--log-file={self.root / 'log' / 'munged.log'}",
            f"--seed-file={self.root / 'munge' / 'munged.seed'}",
        )
        self._wait("munge socket", self.munge_socket.exists, "munged", 30)

    def _start_database(self) -> None:
        datadir = self.root / "mysql"
        self.db_port = _free_port()
        proc = subprocess.run(
            [
                self.bin["mariadb-install-db"],
                "--no-defaults",
                "--user=root",
                f"--datadir={datadir}",
                "--auth-root-authentication-method=normal",
                "--skip-test-db",
            ],
            capture_output=True,
            text=True,
            env=self.env,
            timeout=300,
        )
        if proc.returncode != 0:
            raise ServerError(f"mariadb-install-db failed: {proc.stdout[-2000:]}{proc.stderr}")
        self._spawn(
            "mariadbd",
            self.bin["mariadbd"],
            "--no-defaults",
            "--user=root",
            f"--datadir={datadir}",
            f"--socket={self.root / 'run' / 'mysqld.sock'}",
            f"--pid-file={self.root / 'run' / 'mysqld.pid'}",
            f"--log-error={self.root / 'log' / 'mariadbd.log'}",
            "--bind-address=127.0.0.1",
            f"--port={self.db_port}",
            "--skip-grant-tables",
            "--innodb-buffer-pool-size=64M",
            "--skip-log-bin",
        )
        self._wait(
            f"database on port {self.db_port}", lambda: _port_open(self.db_port), "mariadbd", 120
        )

    def _start_slurm(self) -> None:
        self.dbd_port, self.ctld_port, self.slurmd_port = _free_port(), _free_port(), _free_port()
        auth = f"AuthType=auth/munge\nAuthInfo=socket={self.munge_socket}\n"
        dbd_conf = self.root / "etc" / "slurmdbd.conf"
        dbd_conf.write_text(
            auth + f"DbdAddr=127.0.0.1\nDbdHost={self.node}\nDbdPort={self.dbd_port}\n"
            "SlurmUser=root\nStorageType=accounting_storage/mysql\nStorageHost=127.0.0.1\n"
            f"StoragePort={self.db_port}\nStorageUser=root\nStorageLoc=slurm_acct_db\n"
            f"PidFile={self.root / 'run' / 'slurmdbd.pid'}\n"
            f"LogFile={self.root / 'log' / 'slurmdbd.log'}\nDebugLevel=info\n"
        )
        dbd_conf.chmod(0o600)  # slurmdbd refuses a readable one
        r = self.root
        self.conf.write_text(
            f"ClusterName={CLUSTER_NAME}\nSlurmctldHost={self.node}(127.0.0.1)\n"
            f"SlurmctldPort={self.ctld_port}\nSlurmdPort={self.slurmd_port}\n"
            "SlurmUser=root\nSlurmdUser=root\n" + auth + "CredType=cred/munge\n"
            f"StateSaveLocation={r / 'state'}\nSlurmdSpoolDir={r / 'spool'}\n"
            f"SlurmctldPidFile={r / 'run' / 'slurmctld.pid'}\n"
            f"SlurmdPidFile={r / 'run' / 'slurmd.pid'}\n"
            f"SlurmctldLogFile={r / 'log' / 'slurmctld.log'}\n"
            f"SlurmdLogFile={r / 'log' / 'slurmd.log'}\nSlurmctldDebug=info\nSlurmdDebug=info\n"
            f"TmpFS={r / 'tmp'}\n"
            # no cgroups: processes tracked through /proc, no task binding or memory limits
            "ProctrackType=proctrack/linuxproc\nTaskPlugin=task/none\n"
            "JobAcctGatherType=jobacct_gather/linux\nJobAcctGatherFrequency=10\n"
            "SelectType=select/cons_tres\nSelectTypeParameters=CR_Core_Memory\n"
            "SchedulerType=sched/backfill\nMpiDefault=none\nSwitchType=switch/none\n"
            "ReturnToService=2\nInactiveLimit=0\nKillWait=5\nMinJobAge=300\n"
            "PropagatePrioProcess=0\n"  # jobs run at slurmd's niceness
            "AccountingStorageType=accounting_storage/slurmdbd\n"
            f"AccountingStorageHost={self.node}\nAccountingStoragePort={self.dbd_port}\n"
            # the client side of slurmdbd connections takes its munge socket from here, not
            # from AuthInfo (slurm.conf(5), AccountingStoragePass)
            f"AccountingStoragePass={self.munge_socket}\n"
            "JobCompType=jobcomp/none\n"
            # sacct's Comment column: the plugin's "rule_<rule>_wildcards_<wildcards>"
            "AccountingStoreFlags=job_comment\n"
            f"NodeName={self.node} NodeAddr=127.0.0.1 CPUs={self.cpus} "
            f"RealMemory={self.real_memory_mb} State=UNKNOWN\n"
            f"PartitionName={PARTITION} Nodes={self.node} Default=YES MaxTime=INFINITE State=UP\n"
        )
        self._spawn("slurmdbd", self.bin["slurmdbd"], "-D")
        self._wait(
            f"slurmdbd on port {self.dbd_port}", lambda: _port_open(self.dbd_port), "slurmdbd", 120
        )
        # the cluster's record in the accounting store, before the controller registers
        self.client(self.bin["sacctmgr"], "-i", "add", "cluster", CLUSTER_NAME)
        self._spawn("slurmctld", self.bin["slurmctld"], "-D", "-f", str(self.conf))
        self._wait(
            f"slurmctld on port {self.ctld_port}",
            lambda: _port_open(self.ctld_port),
            "slurmctld",
            60,
        )
        self._spawn("slurmd", self.bin["slurmd"], "-D", "-f", str(self.conf))
        self._wait("the node idle in sinfo", self._node_idle, "slurmd", 120)

    def _node_idle(self) -> bool:
        out = self.client(self.bin["sinfo"], "-h", "-N", "-o", "%N %t", check=False)
        return f"{self.node} idle" in out.split("\n")

    # -- stop -------------------------------------------------------------------------------

    def leftovers(self) -> list[str]:
        """'pid comm' of every live process carrying this cluster's marker, or one of the
        daemons this object started."""
        mine = {p.pid for p in self.procs.values()}
        found = []
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit() or int(entry.name) == os.getpid():
                continue
            pid = int(entry.name)
            if not _alive(pid):
                continue
            if pid in mine or _environ(pid).get(MARKER) == str(self.root):
                found.append(f"{pid} {_comm(pid)}")
        return sorted(found)

    def stop(self, check: bool = True, timeout: float = 60) -> None:
        """Cancel every job, stop the daemons (TERM, then KILL after ``timeout``), in reverse
        start order; with ``check``, ServerError if any process of the cluster is left."""
        if "slurmctld" in self.procs and self.procs["slurmctld"].poll() is None:
            self.client(self.bin["scancel"], "--full", "-u", "root", check=False)
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                queue = self.client(self.bin["squeue"], "-h", "-o", "%i", check=False)
                if not queue.strip():
                    break
                time.sleep(0.5)
        for name in reversed(list(self.procs)):
            proc = self.procs[name]
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
                try:
                    proc.wait(timeout=timeout)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=30)
        deadline = time.monotonic() + 30
        while (left := self.leftovers()) and time.monotonic() < deadline:
            time.sleep(0.5)
        if left:
            for line in left:  # a job step or job process that outlived its daemons
                try:
                    os.kill(int(line.split()[0]), signal.SIGKILL)
                except ProcessLookupError:
                    pass
            if check:
                raise ServerError(f"processes of the test cluster outlived stop: {left}")


def main(argv: list[str]) -> int:
    """``start DIR`` / ``stop DIR``: the cluster as a CI step or for a person to try."""
    if len(argv) != 2 or argv[0] not in ("start", "stop"):
        print("usage: python -m tests.servers.slurm start|stop DIR", file=sys.stderr)
        return 2
    action, root = argv[0], Path(argv[1])
    cluster = SlurmCluster(root)
    if action == "start":
        try:
            cluster.start()
        except ServerError as exc:
            print(exc, file=sys.stderr)
            return 1
        print(f"export SLURM_CONF={cluster.conf}")
        return 0
    # stop: the daemons of an earlier start, by the pids it recorded
    pids = json.loads((cluster.root / "pids.json").read_text())
    subprocess.run(["scancel", "--full", "-u", "root"], env=cluster.env, capture_output=True)
    for name in reversed(list(pids)):
        try:
            os.kill(pids[name], signal.SIGTERM)
        except ProcessLookupError:
            continue
        deadline = time.monotonic() + 60
        while _alive(pids[name]) and time.monotonic() < deadline:
            time.sleep(0.2)
    left = cluster.leftovers()
    if left:
        print(f"left running: {left}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
