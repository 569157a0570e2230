"""Logging set-up shared by the stage entry points (one log file per job, docs/design.md)."""

from __future__ import annotations

import logging
import sys
from pathlib import Path
from types import TracebackType

LOG_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"

ExcInfo = tuple[type[BaseException], BaseException, TracebackType | None]


def setup_logging(log_file: str | Path | None = None, level: int = logging.INFO) -> logging.Logger:
    """Log to stderr and, when given, to the job's log file."""
    handlers: list[logging.Handler] = [logging.StreamHandler(sys.stderr)]
    if log_file:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_file, mode="w"))
    logging.basicConfig(
        level=level,
        format=LOG_FORMAT,
        handlers=handlers,
        force=True,
    )
    return logging.getLogger("graspstab")


def append_record(
    log_file: str | Path,
    name: str,
    level: int,
    message: str,
    exc_info: ExcInfo | None = None,
) -> bool:
    """Append one record (and ``exc_info``'s traceback) to ``log_file`` in the log's format,
    whatever handlers logging has now; False when the file cannot be written (a full disk)."""
    record = logging.LogRecord(name, level, __file__, 0, message, None, exc_info)
    text = logging.Formatter(LOG_FORMAT).format(record)
    try:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        with open(log_file, "a") as fh:
            fh.write(text + "\n")
    except OSError:
        return False
    return True
