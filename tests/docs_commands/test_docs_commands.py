"""The table of every documented command (COMMANDS: run and checked, or exempt) and the tests that hold to it."""

from __future__ import annotations

import os
import re
import shutil
from collections.abc import Iterator

import pytest

from tests.docs_commands.checks import (
    BATCH_SNIPPET_CHECK,
    CHAIN_SNIPPET_CHECK,
    NPZ_SNIPPET_CHECK,
    PYTHON_SNIPPET_CHECK,
    check_compare,
    check_design_by_url,
    check_design_json,
    check_design_stap_csv,
    check_help,
    check_identify,
    check_identify_answer,
    check_identify_recommends,
    check_klipper_section,
    check_mkdocs_build,
    check_mkdocs_serve,
    check_program_cam,
    check_readyz_loop,
    check_recommended_design,
    check_record_written,
    check_resonance_test_written,
    check_served,
    check_sweep_parquet,
    check_sweep_table,
    check_table_iii,
    check_table_iii_csv,
    check_time_optimal_band,
    ok,
)
from tests.docs_commands.extract import COMMAND_LANGUAGES, DATA_LANGUAGES, blocks, command_blocks, commands, key
from tests.docs_commands.sandbox import Exempt, IsTheServer, Run, Runs, Spec, hidden_modules

DASK = "the Dask cluster is tested on a LocalCluster (tests/optim/test_sweeps.py)"

# Every command of a command block, by its first line without its comment.
COMMANDS: dict[str, Spec] = {
    # README.md and docs/index.md: two commands
    "make serve": Exempt(
        "serves until stopped; the tests' server is `vibfree serve`, the same uvicorn app with the same flags "
        "(tests/app/test_python_api.py), and `make -n serve` shows the target's recipe",
        dry_run="make -n serve",
        dry_run_says="uvicorn app.main:app",
    ),
    "make test": Exempt(
        "runs the gates and the whole suite, this test included; `make -n test` shows the target's recipe",
        dry_run="make -n test",
        dry_run_says="python -m pytest",
    ),
    # README.md and docs/try-it.md: a first design by curl
    "until curl -sf localhost:8000/readyz > /dev/null; do sleep 1; done": Run(check_readyz_loop, server=True),
    "curl -s localhost:8000/v1/profiles/pseudo-polynomial -H 'content-type: application/json' -d '{": Run(
        check_table_iii, server=True
    ),
    "curl -s localhost:8000/v1/profiles/time-optimal -H 'content-type: application/json' -d '{": Run(
        check_time_optimal_band, server=True
    ),
    "curl -s 'localhost:8000/v1/profiles/pseudo-polynomial?format=csv&columns=position,velocity,load_position'": Run(
        check_table_iii_csv, server=True
    ),
    # README.md and docs/cli-and-python.md: the command line
    "vibfree --help": Run(check_help),
    "vibfree design stap request.json --csv out.csv": Run(check_design_stap_csv),
    "vibfree design time-optimal request.json --json -": Run(check_design_json),
    "vibfree design stap request.json --csv out.csv --columns all --comments --url http://127.0.0.1:8000": Run(
        check_design_by_url, server=True
    ),
    "vibfree compare request.json": Run(check_compare),
    "vibfree identify record.csv --displacement 0.12 --max-velocity 0.5 --max-acceleration 10": Run(check_identify),
    "vibfree sweep sweep.json --out table.csv": Run(check_sweep_table, extras=("cli",)),
    "vibfree program program.json --csv cam.csv": Run(check_program_cam),
    "vibfree serve --port 8000 --processes 2": IsTheServer(
        check_served,
        "the tests' server runs it (tests/app/server.py) on a free port with one process and one solver worker: "
        "two processes' four workers take ~35 s to warm up on this machine",
    ),
    # README.md and docs/cli-and-python.md: from Python
    "from vibfree import compare, synthesize": Run(ok, python_check=PYTHON_SNIPPET_CHECK),
    "from vibfree import synthesize_many": Run(ok, python_check=BATCH_SNIPPET_CHECK),
    "import vibfree": Run(ok, python_check=CHAIN_SNIPPET_CHECK),
    # docs/api.md: an npz answer
    "import io": Run(ok, server=True, python_check=NPZ_SNIPPET_CHECK),
    # docs/identification.md
    "python3 - <<'EOF'": Run(check_record_written),
    "curl -s -X POST 'http://localhost:8000/v1/identify?displacement=0.05&max_velocity=0.5&max_acceleration=5'": Run(
        check_identify_answer, server=True, needs=("python3 - <<'EOF'",), exclusive=True
    ),
    "curl -s -X POST -H 'content-type: text/csv' --data-binary @record.csv": Run(
        check_recommended_design, server=True, exclusive=True
    ),
    "vibfree identify record.csv --displacement 0.05 --max-velocity 0.5 --max-acceleration 5": Run(
        check_identify_recommends
    ),
    "python3 - <<'KLIPPER'": Run(check_resonance_test_written),
    "vibfree identify raw_data_x.csv --target klipper": Run(check_klipper_section, needs=("python3 - <<'KLIPPER'",)),
    # docs/sweeps.md: a Dask cluster
    "pip install 'vibfree[dask]'": Exempt(
        "installs from the package index; tests/test_packaging.py checks the extra, the tests' environment has it"
    ),
    "dask scheduler": Exempt(f"a Dask scheduler, serving until stopped; {DASK}"),
    "dask worker tcp://<host>:8786 --nthreads 1 --nworkers 8": Exempt(f"needs a scheduler's address; {DASK}"),
    "make serve && .venv/bin/pip install -e '.[dask]'": Exempt(
        "make serve serves until stopped, and pip install reaches the package index"
    ),
    "VIBFREE_DASK_SCHEDULER=tcp://<host>:8786 make serve": Exempt(
        f"needs a scheduler's address, and make serve serves until stopped; {DASK}, and a server given "
        "VIBFREE_DASK_SCHEDULER without the extra in tests/test_packaging.py"
    ),
    # docs/sweeps.md: vibfree sweep
    "vibfree sweep sweep.json --out table.parquet --url http://127.0.0.1:8000": Run(
        check_sweep_parquet, server=True, extras=("parquet",)
    ),
    # README.md: the documentation site
    ".venv/bin/mkdocs serve -a 127.0.0.1:8001": Run(check_mkdocs_serve, extras=("test",), background="/"),
    ".venv/bin/mkdocs build --strict": Run(check_mkdocs_build, extras=("test",)),
}


# --- the tests ---------------------------------------------------------------------------------------------------


def test_every_block_says_what_it_is():
    # A block without a language (or with another) could be commands nobody runs.
    unknown = [str(b) for b in blocks() if b.language not in COMMAND_LANGUAGES | DATA_LANGUAGES]
    assert not unknown, f"fence these as {sorted(COMMAND_LANGUAGES)} (commands) or {sorted(DATA_LANGUAGES)}"
    assert {b.language for b in blocks()} >= {"sh", "python", "text", "json"}


def test_data_blocks_hold_no_commands():
    command = re.compile(r"^\s*(\$ |curl |vibfree |python3? |pip |make |docker |kubectl |\.venv/)", re.M)
    suspicious = [str(b) for b in blocks() if b.language in DATA_LANGUAGES and command.search(b.body)]
    assert not suspicious, "a command fenced as data: fence it as sh (and list it in COMMANDS)"


def test_every_command_is_run_or_exempt():
    found = {key(c) for body, places in command_blocks().items() for c in commands(body, places[0].language)}
    missing = sorted(found - set(COMMANDS))
    assert not missing, f"new commands: add each to COMMANDS, with its check or the reason it cannot run: {missing}"
    stale = sorted(set(COMMANDS) - found)
    assert not stale, f"COMMANDS lists commands that no document has any more: {stale}"


def test_the_readme_python_snippet_imports_only_what_pip_install_installs():
    # Issue 24: the README's snippet runs after make serve, which installs no test dependency (pandas).
    hidden = set(hidden_modules().split(","))
    assert {"pandas", "pytest", "tqdm", "pyarrow", "dask", "httpx2", "mkdocs"} <= hidden
    assert not hidden & {"numpy", "scipy", "casadi", "fastapi", "uvicorn", "pydantic", "orjson", "vibfree"}
    (snippet,) = [b.body for b in blocks() if b.document == "README.md" and b.language == "python"]
    assert isinstance(COMMANDS[key(snippet)], Run)


@pytest.fixture(scope="module")
def runs(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Runs]:
    selected = [
        item.callspec.params["body"]
        for item in request.session.items
        if getattr(item, "originalname", "") == "test_command_block" and hasattr(item, "callspec")
    ]
    started = Runs(tmp_path_factory.mktemp("docs-commands"), selected, COMMANDS)
    try:
        yield started
    finally:
        started.close()


BODIES = command_blocks()


@pytest.mark.parametrize("body", list(BODIES), ids=[", ".join(str(b) for b in BODIES[body]) for body in BODIES])
def test_command_block(body: str, runs: Runs):
    if "| jq " in body and shutil.which("jq") is None:  # make test installs it (scripts/ensure-test-tools.sh)
        if os.environ.get("CI") == "true":
            pytest.fail("jq is missing: `make test` installs Debian's jq (scripts/ensure-test-tools.sh)")
        pytest.skip("jq is not installed (run scripts/ensure-test-tools.sh)")
    for command, spec, ran in runs.result(body):
        assert spec is not None, f"not in COMMANDS: {key(command)!r}"
        if isinstance(spec, Exempt):
            assert spec.reason
            if spec.dry_run:
                assert ran is not None and ran.returncode == 0 and spec.dry_run_says in ran.stdout, ran
        else:
            assert ran is not None
            spec.check(ran)
