"""The suite's marker contract and order, on every collection and every test (loaded by the
``-p tests.plugins.markers`` in pyproject's addopts).

* A test that reaches the toy run (the session fixture ``run`` in tests/conftest.py, directly or
  through another fixture) or runs Snakemake jobs for real (its environment from ``asset_env``)
  must carry ``@pytest.mark.workflow``, so ``pytest -m "not workflow"`` never builds or runs them.
  The fixture closure is known at collection for fixtures named in signatures; a fixture obtained
  with ``request.getfixturevalue`` is only known once the test has set it up, so the same check
  runs again after each test (public ``request.fixturenames``).
* The tests that use the toy run are collected first, then the other workflow tests: the toy
  run is the suite's longest chain (it takes minutes, and several tests run Snakemake again from
  it), so under ``-n 2`` it starts at once while the other worker takes the unit tests. It is
  built once per session, by whichever worker asks first (tests/toy_workflow.py
  ``shared_toy_run``). The order within each part is the collection's.
"""

from __future__ import annotations

import pytest

TOY_RUN = "run"
JOB_ENV = "asset_env"


def missing_marks(fixturenames: set[str], node: pytest.Item) -> list[str]:
    """The marks ``node`` lacks for the fixtures it uses (empty when none)."""
    uses = TOY_RUN in fixturenames or JOB_ENV in fixturenames
    return ["@pytest.mark.workflow"] if uses and not node.get_closest_marker("workflow") else []


def _message(node: pytest.Item, missing: list[str]) -> str:
    return (
        f"{node.nodeid} uses the toy run or runs Snakemake jobs but lacks {', '.join(missing)} "
        "(tests/plugins/markers.py)"
    )


@pytest.hookimpl(tryfirst=True)  # before -m deselects
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    bad = [_message(i, m) for i in items if (m := missing_marks(set(i.fixturenames), i))]
    if bad:
        raise pytest.UsageError("marker contract:\n" + "\n".join(bad))
    # the toy run's tests, then the other workflow tests (the finished-run report among them),
    # then the rest; stable
    items[:] = sorted(items, key=lambda i: (TOY_RUN not in i.fixturenames,
                                            i.get_closest_marker("workflow") is None))  # fmt: skip


@pytest.fixture(autouse=True)
def _marker_contract(request: pytest.FixtureRequest):
    """After the test: the same check on every fixture it set up, dynamic ones included."""
    yield
    missing = missing_marks(set(request.fixturenames), request.node)
    if missing:
        pytest.fail(_message(request.node, missing), pytrace=False)
