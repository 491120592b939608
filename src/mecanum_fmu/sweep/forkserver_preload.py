"""Imported first by the sweep's fork server (multiprocessing's forkserver preload list, set
by cluster._forkserver_ignoring_ctrl_c), nowhere else: the server ignores SIGINT and SIGTERM
from here on, and multiprocessing gives each worker it forks the handlers the server had before
its own set-up, so every local worker ignores the Ctrl-C a terminal sends to the whole process
group, and the SIGTERM that `kill -TERM -PGID` (or a service manager) sends to it: the client
stops the sweep and closes its workers (their nanny's stop message, SIGKILL if one hangs), as
multiprocessing's resource tracker also leaves those signals to its parent. A worker killed by
the group's SIGTERM was restarted by its nanny through a fork server started anew (the old one
had died of the same signal) while the client closed the cluster; a restart still under way
when the client left was an orphan that wrote a traceback into the sweep's stderr. The server
is started with SIGINT blocked, so a Ctrl-C before this line stays pending and is discarded
here."""
import signal
import sys

if sys.argv[:1] == ["-c"] and "multiprocessing.forkserver" in sys.modules:  # the server only
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
