# Two commands do all the set-up on a fresh machine: `make serve` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
HOST   ?= 127.0.0.1
PORT   ?= 8000
# docs/deployment.md: JSON logs are the app's (its own access line), limits on idle and slow clients.
SERVE_FLAGS ?= --no-access-log --no-server-header --http h11 --timeout-keep-alive 5 \
	--h11-max-incomplete-event-size 16384 --timeout-graceful-shutdown 30

.PHONY: serve test bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.installed-serve: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e ".[test]"
	touch $@ $(VENV)/.installed-serve

# VIBFREE_PROCESSES HTTP processes (default one per core) under uvicorn's supervisor, each with its solver pool;
# their metrics in a fresh directory per start (prometheus_client multiprocess mode, docs/deployment.md).
PROCESSES = $$($(BIN)/python -c 'from app.settings import Settings; print(Settings().processes)')

serve: $(VENV)/.installed-serve  ## run the service on http://$(HOST):$(PORT) (docs at /docs)
	export PROMETHEUS_MULTIPROC_DIR=$$(mktemp -d -t vibfree-metrics-XXXXXX) VIBFREE_PROCESSES=$(PROCESSES) \
	OMP_NUM_THREADS=$${OMP_NUM_THREADS:-1} OPENBLAS_NUM_THREADS=$${OPENBLAS_NUM_THREADS:-1} \
	MKL_NUM_THREADS=$${MKL_NUM_THREADS:-1} && \
	$(BIN)/uvicorn app.main:app --workers $$VIBFREE_PROCESSES --host $(HOST) --port $(PORT) $(SERVE_FLAGS)

test: $(VENV)/.installed-test  ## lint, format and type gates, the docs site, then the whole test suite (installs Debian's chromium)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy --strict models optim runtime
	$(BIN)/mypy --strict app vibfree
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --site-dir site  # docs/: a broken link or anchor fails (not --quiet: it hides them)
	bash scripts/ensure-test-tools.sh
	$(BIN)/python -m pytest -n 2 --dist loadscope  # two processes; tests marked serial run alone (tests/conftest.py)

bench: $(VENV)/.installed-test  ## run the benchmarks whose figures are in docs/benchmarks.md
	$(BIN)/python bench/simulation.py
	$(BIN)/python bench/pipeline_stap.py  # one STAP closed form in-process, stage by stage
	$(BIN)/python bench/http_io.py  # the HTTP path: 100k /v1/simulate (JSON, npz, fields=), 1k STAP
	$(BIN)/python bench/throughput.py  # req/s at 1, 4, 8 clients: one process against the defaults
	$(BIN)/python bench/worker_memory.py  # worker RSS after 200 distinct plants
	$(BIN)/python bench/sweeps.py  # a 50-plant sweep against slowest design x points / workers; a LocalCluster
	$(BIN)/python bench/pseudo_polynomial.py
	$(BIN)/python bench/compare.py  # includes bench/pseudo_polynomial_duration.py
	$(BIN)/python bench/time_optimal.py  # the benchmark moves against the exact minimum and the shaped commands
	$(BIN)/python bench/time_optimal_random.py  # 200 seeded random moves against ZV-shaped Ruckig and an 800-step LP
	$(BIN)/python bench/time_optimal_speed.py cad35ac  # in-process speed against cad35ac (before the certified fast path)
	$(BIN)/python bench/time_optimal_batch.py  # 1,000 nominal moves through vibfree.synthesize_many, one process and two
	$(BIN)/python bench/csv_export.py  # the CSV table beside the JSON answer
	$(BIN)/python bench/health_under_load.py  # /healthz and /readyz while slow solves saturate the pool
	$(BIN)/python bench/determinism.py  # the same answers idle and with 8 clients sending slow solves
	$(BIN)/python bench/fuzz.py  # 2000 schemathesis cases per operation (--cases N)

clean:
	rm -rf $(VENV) .pytest_cache site
