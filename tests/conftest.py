"""The suite on several processes (pytest-xdist), and the tests whose verdict must not depend on the others.

``make test`` runs ``pytest -n 2 --dist loadscope``: each worker takes whole modules (a module's server or pool
starts once; a session fixture, such as tests/app's client, starts once per worker).

A test marked ``serial`` measures something that another test beside it could change: a wall-clock bound or a time
budget per answer, the processes it kills and the children it counts, a browser's timing. Every module holding
one runs on the first worker, gw0, one after the other, before gw0 takes any other module; the other workers take
only the other modules, and run niced (``BULK_NICENESS``, with every process they start), so that on a busy machine
the CPU goes to gw0's tests first: what a serial test measures is what it would measure with no other test running,
while the other worker still uses whatever CPU is left. The ordinary tests have no such bounds (their waits are
timeouts of a minute or more). Without xdist (``-p no:xdist``, ``-n 0``) there is one process and nothing changes.
"""

from __future__ import annotations

import json
import os
import sys
from collections import OrderedDict
from pathlib import Path
from typing import Any

import pytest

from vibfree.cli import one_blas_thread

one_blas_thread()  # as the service's workers and the benchmarks run (a design's last bits depend on it)
NUMPY_BEFORE_CONFTEST = "numpy" in sys.modules  # (then the setting above came too late for this process)

SERIAL = "serial"
PRIORITY_WORKER = "gw0"
BULK_NICENESS = 10  # CFS weight 110 against gw0's 1024: gw0 gets nine tenths of a contended core
# Modules first, the longest first, so that no long module starts last (the others: most tests first).
FIRST = ("tests/app/test_fuzz.py", "tests/app/test_api.py", "tests/app/test_compare_api.py")
SERIAL_IDS = "serial-nodeids.json"  # written by the workers in the run's temporary directory, read by the scheduler


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{SERIAL}: its module runs on the first xdist worker, the others niced (wall-clock bounds, process trees)",
    )
    workerinput = getattr(config, "workerinput", None)
    if workerinput is not None and int(workerinput["workercount"]) > 1 and workerinput["workerid"] != PRIORITY_WORKER:
        os.nice(BULK_NICENESS)  # before any test: its threads and processes inherit it


def _run_dir(config: pytest.Config) -> Path:
    """The run's temporary directory: the controller's basetemp, a worker's basetemp's parent (popen-gw<N>)."""
    basetemp = Path(config._tmp_path_factory.getbasetemp())  # type: ignore[attr-defined]
    return basetemp.parent if hasattr(config, "workerinput") else basetemp


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Schemathesis' items (tests/app/test_fuzz.py, one per operation) all have the test function's node id; their
    names say the operation. pytest-xdist tells items apart by node id (grouping by module keeps one of equal ids,
    and the others never run): each such item gets its operation in its id, as pytest gives a parametrized one
    (``test_every_operation_survives_fuzzing[POST /v1/compare]``). A worker then writes the serial tests' ids for
    the scheduler."""
    counts: dict[str, int] = {}
    for item in items:
        counts[item.nodeid] = counts.get(item.nodeid, 0) + 1
    for item in items:
        label = getattr(item, "operation_label", None)
        if counts[item.nodeid] > 1 and label:
            node_id = getattr(item, "_id", None)
            if node_id is not None and hasattr(node_id, "with_params"):  # pytest >= 9.2: a structured NodeId
                if node_id.params is None:
                    item._id = node_id.with_params(label)  # type: ignore[attr-defined]
            else:
                item._nodeid = f"{item.nodeid}[{label}]"  # type: ignore[attr-defined]
    ids = [item.nodeid for item in items]
    assert len(set(ids)) == len(ids), "two test items share a node id: pytest-xdist would run only one"
    if hasattr(config, "workerinput"):
        serial = sorted(item.nodeid for item in items if item.get_closest_marker(SERIAL) is not None)
        path = _run_dir(config) / SERIAL_IDS
        partial = path.with_suffix(f".{os.getpid()}")
        partial.write_text(json.dumps(serial))
        os.replace(partial, path)  # every worker writes the same list; the scheduler reads it whole


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: none without it (-p no:xdist)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    """With ``--dist loadscope``: whole modules, those with a serial test on the priority worker only."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Scheduling(LoadScopeScheduling):  # type: ignore[misc]
        ordered = False
        serial_scopes: frozenset[str] = frozenset()

        def _order(self) -> None:
            path = _run_dir(config) / SERIAL_IDS
            serial = json.loads(path.read_text()) if path.exists() else []
            self.serial_scopes = frozenset(self._split_scope(nodeid) for nodeid in serial)

            def rank(scope: str) -> tuple[int, int]:
                return (0 if scope in self.serial_scopes else 1, FIRST.index(scope) if scope in FIRST else len(FIRST))

            self.workqueue = OrderedDict(sorted(self.workqueue.items(), key=lambda unit: rank(unit[0])))
            self.ordered = True

        def _assign_work_unit(self, node: Any) -> None:
            if not self.ordered:
                self._order()
            # The priority worker takes the serial modules first; if it is gone (crashed), any worker takes them.
            priority = PRIORITY_WORKER not in {n.gateway.id for n in self.nodes} or node.gateway.id == PRIORITY_WORKER
            scope = next((s for s in self.workqueue if priority or s not in self.serial_scopes), None)
            if scope is None:  # only serial modules are left, for the priority worker: this one is done
                return
            work_unit = self.workqueue.pop(scope)
            self.assigned_work.setdefault(node, {})[scope] = work_unit
            collection = self.registered_collections[node]
            node.send_runtest_some([collection.index(nodeid) for nodeid, done in work_unit.items() if not done])

    return Scheduling(config, log)
