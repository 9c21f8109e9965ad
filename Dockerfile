# Vibration-free motion profile service.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /srv
COPY pyproject.toml README.md ./
COPY models ./models
COPY optim ./optim
COPY app ./app
COPY vibfree ./vibfree
RUN pip install --no-cache-dir . \
    && groupadd --gid 10001 vibfree \
    && useradd --create-home --uid 10001 --gid 10001 --shell /usr/sbin/nologin vibfree

USER 10001:10001
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=4).status != 200)"]
# README "Deployment": the app writes its own JSON access line; behind a reverse proxy, pass
# FORWARDED_ALLOW_IPS (uvicorn reads it) with the proxy's address so --proxy-headers trusts it.
CMD ["uvicorn", "app.main:app", "--host", "0.0.0.0", "--port", "8000", "--no-access-log", "--no-server-header", "--http", "h11", "--timeout-keep-alive", "5", "--h11-max-incomplete-event-size", "16384", "--timeout-graceful-shutdown", "30", "--proxy-headers"]
