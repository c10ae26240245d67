"""What a Dask worker does for multilayer besides running jobs: leave Ctrl-C to the command, stop runs when told.

A Ctrl-C in a terminal reaches every process of the foreground group: the
command and the worker processes of its embedded local cluster alike; a
batch system's SIGTERM (the end of a job's time) reaches every process of
the job.  The command stops the runs itself (:func:`stop_tasks`, then it
closes the cluster), so a worker of that cluster ignores SIGINT instead of
dying with a traceback of ``KeyboardInterrupt``, and a SIGTERM lets its runs
finish their step, ``interrupted``, before the worker ends
(:func:`dask_setup`, the workers' preload).

A run on a worker goes on in one of the worker's threads, where it catches
no signal itself (:func:`multilayer.runner.loop.interruptible`):
:func:`stop_tasks` stops it as the signal would.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Collection
from typing import Any

from multilayer.runner import loop

#: seconds a worker that got SIGTERM waits for its runs to finish their step before it ends all the same
STOP_WAIT = 60.0


def dask_setup(worker: Any) -> None:
    """The preload of the embedded cluster's workers, called by Dask in the worker process's main thread: ignore
    SIGINT, which the command answers for the whole cluster; on SIGTERM stop the runs, then end (exit code 143)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _on_sigterm)
        if hasattr(signal, "pthread_sigmask"):  # the nanny started this process with both blocked (see executor)
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})


def _on_sigterm(signum: int, frame: object) -> None:
    _STOPPED[ALL] = "SIGTERM"  # no task of this worker starts a run any more
    loop.stop("SIGTERM")
    threading.Thread(target=_end_when_stopped, name="multilayer SIGTERM", daemon=True).start()


def _end_when_stopped() -> None:
    """End this worker process once its runs have stopped (their folders written), as SIGTERM would have."""
    deadline = time.monotonic() + STOP_WAIT
    while loop.runs() and time.monotonic() < deadline:
        time.sleep(0.05)
    os._exit(128 + signal.SIGTERM)


#: the tasks :func:`stop_tasks` stopped in this worker process, with the signal's name: one that starts later
#: (it was about to when it was stopped) does not run; :data:`ALL` when SIGTERM is ending the worker
_STOPPED: dict[str, str] = {}
ALL = "*"


def stop_tasks(keys: Collection[str], name: str, dask_worker: Any = None) -> list[str]:
    """Stop the runs of the tasks ``keys`` in this worker, as the signal ``name`` would: a run going on finishes its
    step and returns ``interrupted``; one that has not begun yet will not (:func:`stopped_here`).  The keys among
    ``keys`` this worker is running.  For ``Client.run``, which passes ``dask_worker``."""
    _STOPPED.update(dict.fromkeys(keys, name))
    running = [(thread, key) for thread, key in list(dask_worker.active_threads.items()) if key in keys]
    for thread, _ in running:
        loop.stop(name, thread)
    return [key for _, key in running]


def stopped_here() -> str | None:
    """The signal's name when the task this thread runs has been stopped by :func:`stop_tasks`, else None
    (always outside a Dask worker)."""
    if not _STOPPED:
        return None
    # only a worker's process gets here, so Dask is installed
    from distributed import get_worker

    try:
        key = get_worker().active_threads.get(threading.get_ident())
    except ValueError:  # not in a worker's thread
        return None
    return _STOPPED.get(key, _STOPPED.get(ALL))
