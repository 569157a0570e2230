"""A gate in one replay job, for the kill-mid-replay test (tests/test_workflow.py).

The test copies this file as ``sitecustomize.py`` into a folder it puts first on the run's
PYTHONPATH, and sets ``GRASPSTAB_TEST_REPLAY_GATE`` to a folder of its own. Every Python process
of that run (Snakemake and its script jobs) then imports it at start-up; in the one that imports
``graspstab.replay.replay_grasps``, ``run_replay`` is wrapped. The first replay job to reach its
second grasp claims the gate (an exclusive create, so exactly one job does), writes ``blocked``
in the gate folder and waits there until it is killed. The test waits for ``blocked`` and then
kills: the run is known to be mid-replay (one grasp of that shard replayed, its outputs not
written) and cannot finish before the kill, whatever the machine's speed. Without the variable
this module does nothing.
"""

from __future__ import annotations

import importlib.util
import os
import sys
import threading

GATE = os.environ.get("GRASPSTAB_TEST_REPLAY_GATE")
TARGET = "graspstab.replay.replay_grasps"
AT_CALL = 2  # the second grasp of the job's shard


def _gated(run_replay):
    calls = 0

    def wrapper(*args, **kwargs):
        nonlocal calls
        calls += 1
        if calls == AT_CALL:
            try:
                fd = os.open(os.path.join(GATE, "claimed"), os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:  # another job holds the gate: this one runs through
                pass
            else:
                os.write(fd, str(os.getpid()).encode())
                os.close(fd)
                open(os.path.join(GATE, "blocked"), "w").close()
                threading.Event().wait()  # until SIGKILL
        return run_replay(*args, **kwargs)

    return wrapper


class _PatchOnImport:
    """Meta-path finder: wraps the module's run_replay right after the module has executed."""

    def find_spec(self, name, path=None, target=None):
        if name != TARGET:
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        execute = spec.loader.exec_module

        def exec_module(module):
            execute(module)
            module.run_replay = _gated(module.run_replay)

        spec.loader.exec_module = exec_module
        return spec


if GATE:
    sys.meta_path.insert(0, _PatchOnImport())
