"""JSON logs: every log line one JSON object on stderr (structlog), in the server and in its solver workers."""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable
from typing import Any, TextIO

import structlog

#: The service's own loggers, shown from INFO (everything else from WARNING, the root's level).
APP_LOGGERS = ("app", "optim", "runtime", "models", "vibfree")


class _StderrHandler(logging.StreamHandler):  # type: ignore[type-arg]
    """A handler writing to whatever ``sys.stderr`` is at the time of each record (test capture included)."""

    @property
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, _value: TextIO) -> None:  # StreamHandler.__init__ assigns it
        pass


def _drop_color_message(_: Any, __: str, event_dict: structlog.typing.EventDict) -> structlog.typing.EventDict:
    event_dict.pop("color_message", None)  # uvicorn's ANSI-coloured copy of its message
    return event_dict


def _formatter() -> structlog.stdlib.ProcessorFormatter:
    """The formatter of every line: a stdlib record (foreign) or a structlog event, as one JSON object."""
    return structlog.stdlib.ProcessorFormatter(
        foreign_pre_chain=[
            structlog.contextvars.merge_contextvars,  # the request id, in the thread that logs
            structlog.stdlib.add_logger_name,
            structlog.stdlib.add_log_level,
            structlog.stdlib.ExtraAdder(),
            _drop_color_message,
            structlog.processors.TimeStamper(fmt="iso", utc=True),
        ],
        processors=[
            structlog.stdlib.ProcessorFormatter.remove_processors_meta,
            structlog.processors.format_exc_info,
            structlog.processors.JSONRenderer(),
        ],
    )


def configure_logging(level: int | str = logging.INFO) -> None:
    """One JSON object per line on stderr for structlog and stdlib loggers alike. Idempotent."""
    root = logging.getLogger()
    if not any(isinstance(h, _StderrHandler) for h in root.handlers):
        structlog.configure(
            processors=[
                structlog.contextvars.merge_contextvars,
                structlog.stdlib.filter_by_level,
                structlog.stdlib.add_logger_name,
                structlog.stdlib.add_log_level,
                structlog.stdlib.PositionalArgumentsFormatter(),
                structlog.processors.TimeStamper(fmt="iso", utc=True),
                structlog.processors.StackInfoRenderer(),
                structlog.stdlib.ProcessorFormatter.wrap_for_formatter,
            ],
            logger_factory=structlog.stdlib.LoggerFactory(),
            wrapper_class=structlog.stdlib.BoundLogger,
            cache_logger_on_first_use=True,
        )
        handler = _StderrHandler()
        handler.setFormatter(_formatter())
        root.addHandler(handler)
    logging.captureWarnings(True)  # a numpy RuntimeWarning is a JSON line too (logger py.warnings), not raw stderr
    for name in APP_LOGGERS:
        logging.getLogger(name).setLevel(level)
    # uvicorn configures its loggers (dictConfig) before it imports the app: route its error logger,
    # and its access logger when it is on (it is off with --no-access-log), through the JSON handler.
    for name in ("uvicorn", "uvicorn.error", "uvicorn.access"):
        logger = logging.getLogger(name)
        if name == "uvicorn.access" and not logger.handlers and not logger.propagate:
            continue  # disabled by --no-access-log
        logger.handlers.clear()
        logger.propagate = True


def start_worker(warm_up: Callable[[], None]) -> None:
    """A solver worker's start (run in the new process): JSON logs like the server's, then the warm-up.

    A failed warm-up is logged as one JSON line with its traceback; the process then exits and the
    pool retries with back-off.
    """
    configure_logging()
    try:
        warm_up()
    except Exception:
        logging.getLogger("app.worker").exception("solver worker warm-up failed")
        raise SystemExit(1) from None
