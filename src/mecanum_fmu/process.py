"""The process and its signals: the one hard exit that every entry point (CLI, pytest,
benches, host children) uses, and how Ctrl-C and SIGTERM reach a run (latched while FMUs or a
sweep's client run, raised as KeyboardInterrupt / Terminated elsewhere, deferred while result
files are completed). Imports nothing of the package above it."""
from __future__ import annotations

import os
import shutil
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Iterator, NoReturn


def exit_now(code: int) -> NoReturn:
    """Leave without interpreter shutdown: with pythonfmu FMUs loaded, CPython's finalization
    aborts now and then ("corrupted double-linked list", ~1 run in 30, after every file was
    written). Flushes the standard streams and removes the FMU extraction folders first, the
    only clean-up that matters once every result file is closed."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (BrokenPipeError, ValueError):   # the reader left (`| head`) or it is closed
            pass
    if "mecanum_fmu.runtime" in sys.modules:       # nothing was extracted otherwise
        from .runtime import RUNTIME
        RUNTIME.remove_extractions()
    if "multiprocessing" in sys.modules:   # its pymp-* folder (the sweep's fork server socket)
        folder = sys.modules["multiprocessing"].current_process()._config.get("tempdir")
        if folder:
            shutil.rmtree(folder, ignore_errors=True)
    os._exit(code)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's KeyboardInterrupt wherever the run does not latch it
    (ctrl_c_latched does, while the FMUs run): the same clean-up runs, and the
    CLI exits with 143."""


def raise_terminated(signum, frame) -> NoReturn:
    raise Terminated()


@contextmanager
def sigterm_raises() -> Iterator[None]:
    """SIGTERM raises Terminated instead of ending the process at once (so that temporary
    files are removed and what was recorded is kept). Only on the main thread and when the
    default handler is installed; restored afterwards."""
    install = (threading.current_thread() is threading.main_thread()
               and signal.getsignal(signal.SIGTERM) == signal.SIG_DFL)
    if install:
        signal.signal(signal.SIGTERM, raise_terminated)
    try:
        yield
    finally:
        if install:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


class SignalFlag(list):
    """What ctrl_c_latched yields: flag[0] is the signal number (0 while none came). Inside
    `with flag.raising():` a signal also raises (KeyboardInterrupt, SIGTERM Terminated), for
    work that may simply stop (an evaluation, plots); flag[0] is set either way, so a signal
    that lands as the block ends is still seen."""

    def __init__(self):
        super().__init__([0])
        self.raises = False

    def __call__(self, number, frame) -> None:
        self[0] = self[0] or number
        if self.raises:
            self.raises = False
            raise Terminated() if number == signal.SIGTERM else KeyboardInterrupt()

    @contextmanager
    def raising(self) -> Iterator[None]:
        self.raises = True
        try:
            yield
        finally:
            self.raises = False


@contextmanager
def ctrl_c_latched() -> Iterator[SignalFlag]:
    """While the FMUs run, Ctrl-C (and SIGTERM) only set a flag that the stepping loop checks
    once per step: flag[0] is the signal number, 0 while none came (see SignalFlag).

    The bundled FMUs run Python code on this thread, so Python's default SIGINT handler would
    raise KeyboardInterrupt inside an FMU call about 2 times in 3, and pythonfmu turns that
    into fmi2Fatal (the run fails instead of stopping, the instance cannot even be freed);
    SIGTERM would end the process with nothing kept. Only on the main thread and for a signal
    whose handler is the default one (or sigterm_raises'); elsewhere the flag stays 0
    and the signals behave as usual."""
    flag = SignalFlag()
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for signum, defaults in ((signal.SIGINT, (signal.default_int_handler,)),
                                 (signal.SIGTERM, (signal.SIG_DFL, raise_terminated))):
            if signal.getsignal(signum) in defaults:
                previous[signum] = signal.signal(signum, flag)
    try:
        yield flag
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM wait until the block has finished (a few result files being
    completed), then raise KeyboardInterrupt or Terminated. Main thread only; elsewhere the
    block runs as it is."""
    with ctrl_c_latched() as flag:
        yield
    if flag[0] == signal.SIGTERM:
        raise Terminated()
    if flag[0]:
        raise KeyboardInterrupt()
