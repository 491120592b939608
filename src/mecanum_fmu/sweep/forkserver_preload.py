"""Imported first by the sweep's fork server (multiprocessing's forkserver preload list, set
by cluster._forkserver_ignoring_ctrl_c), nowhere else: the server ignores SIGINT from here
on, and multiprocessing gives each worker it forks the handler the server had before its own
set-up, so every local worker ignores the Ctrl-C a terminal sends to the whole process group
(the client stops the sweep). The server is started with SIGINT blocked, so a Ctrl-C before
this line stays pending and is discarded here."""
import signal
import sys

if sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules:  # the server only
    signal.signal(signal.SIGINT, signal.SIG_IGN)
