# Vibration-free motion profile service.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    OMP_NUM_THREADS=1 \
    OPENBLAS_NUM_THREADS=1 \
    MKL_NUM_THREADS=1 \
    NUMBA_CACHE_DIR=/tmp/numba-cache

WORKDIR /srv
COPY pyproject.toml README.md ./
COPY models ./models
COPY optim ./optim
COPY runtime ./runtime
COPY app ./app
COPY vibfree ./vibfree
# DL3013: this installs the project itself (with its dask extra), whose dependencies pyproject.toml bounds
# hadolint ignore=DL3013
RUN pip install --no-cache-dir ".[dask]" \
    && groupadd --gid 10001 vibfree \
    && useradd --create-home --uid 10001 --gid 10001 --shell /usr/sbin/nologin vibfree

USER 10001:10001
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status != 200)"]
# docs/deployment.md: `vibfree serve` runs uvicorn with the Makefile's flags, VIBFREE_PROCESSES HTTP processes
# (set it to the container's CPU limit: the container sees the node's cores) and a fresh metrics directory in /tmp
# (writable: an emptyDir under a read-only root). Behind a reverse proxy, pass FORWARDED_ALLOW_IPS (uvicorn reads
# it) with the proxy's address so --proxy-headers trusts it.
CMD ["vibfree", "serve", "--host", "0.0.0.0", "--port", "8000", "--proxy-headers"]
