"""Leaving the process: the one hard exit that every entry point (CLI, pytest, benches, host
children) uses."""
from __future__ import annotations

import os
import sys
from typing import NoReturn


def exit_now(code: int) -> NoReturn:
    """Leave without interpreter shutdown: with pythonfmu FMUs loaded, CPython's finalization
    aborts now and then ("corrupted double-linked list", ~1 run in 30, after every file was
    written). Flushes the standard streams and removes the FMU extraction folders first, the
    only clean-up that matters once every result file is closed."""
    sys.stdout.flush()
    sys.stderr.flush()
    if "mecanum_fmu.runtime" in sys.modules:       # nothing was extracted otherwise
        from .runtime import RUNTIME
        RUNTIME.remove_extractions()
    os._exit(code)
