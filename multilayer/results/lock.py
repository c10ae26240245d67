"""The lock of a results folder: one run at a time.

``.lock`` is ``flock``'d by the run that holds the folder and holds its PID
and host; a lock file of a process that is gone is taken over, and one a
live process of this host wrote without ``flock`` is respected.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from collections.abc import Sequence
from pathlib import Path

from multilayer.results.files import NOFOLLOW, ResultsError

#: the lock of the folder (``flock``; the holder's PID and host in it)
LOCK = ".lock"


def take(folder: Path) -> int:
    """Take ``folder/.lock`` (``flock``, our PID and host in it): its open descriptor; refuse a folder a live run holds."""
    lock = folder / LOCK
    for _ in range(1000):
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | NOFOLLOW, 0o666)
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise ResultsError(f"{lock} is a symbolic link, not a lock of multilayer: remove it") from None
            raise ResultsError(f"the results folder {folder} is not writable: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            who = holder(fd) if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES) else ""
            os.close(fd)
            if who is None:
                continue  # the holder released it meanwhile: try again
            raise ResultsError(f"{folder} is in use by another run ({who or exc.strerror}); "
                               f"choose another --out") from None
        try:  # a releasing run unlinks the lock before unlocking it: ours must be the one in the folder
            same = os.path.samestat(os.fstat(fd), os.stat(lock, follow_symlinks=False))
        except FileNotFoundError:
            same = False
        if not same:
            os.close(fd)
            continue
        recorded = os.pread(fd, 256, 0).decode(errors="replace").split()
        if live_elsewhere(recorded):  # a lock file of a run that took it without flock
            os.close(fd)
            raise ResultsError(f"{folder} is in use by another run (PID {recorded[0]}); choose another "
                               f"--out, or remove {lock} if that process is not a run")
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()} {socket.gethostname()}\n".encode(), 0)
        except OSError as exc:  # a full disk
            os.close(fd)
            raise ResultsError(f"cannot write in the results folder {folder}: {exc.strerror or exc}") from None
        return fd
    raise ResultsError(f"could not take {lock}: it keeps changing")


def release(folder: Path, fd: int) -> None:
    """Give the lock ``fd`` of ``folder`` up: ``.lock`` is removed (if it is still ours), then unlocked."""
    lock = folder / LOCK
    try:
        if os.path.samestat(os.fstat(fd), os.stat(lock, follow_symlinks=False)):
            lock.unlink()
    except OSError:
        pass
    os.close(fd)  # unlocks


def holder(fd: int) -> str | None:
    """Who holds the lock ``fd`` is open on: 'PID n on host h'; None when nobody does any more."""
    for _ in range(50):
        text = os.pread(fd, 256, 0).decode(errors="replace").split()
        if text:
            pid = text[0]
            host = text[1] if len(text) > 1 else ""
            return f"PID {pid}" + (f" on {host}" if host and host != socket.gethostname() else "")
        try:  # not written yet, or the holder is gone
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            time.sleep(0.002)
            continue
        return None
    return "PID unknown"



def live_elsewhere(recorded: Sequence[str]) -> bool:
    """True when a lock's text (``PID [host]``) names a live process of this host other than us."""
    try:
        pid = int(recorded[0]) if recorded else 0
    except ValueError:
        return False
    host = recorded[1] if len(recorded) > 1 else socket.gethostname()
    return pid > 0 and pid != os.getpid() and host == socket.gethostname() and alive(pid)


def alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process: alive
        return True
    return True

