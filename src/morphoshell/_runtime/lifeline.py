"""Workers that end when the process they work for has gone.

A campaign's worker processes (a process pool's or a Dask ``LocalCluster``'s)
would otherwise go on fitting and writing results after the campaign's own
process was killed: nobody reads them, and they race a restarted campaign
for the same files.  The campaign sends its :func:`owner` with each task; a
worker on the same machine :func:`watch`-es it from a daemon thread and
exits when it has gone.  A worker on another machine (a remote Dask
scheduler's) cannot see the process and is left to its scheduler.
"""
from __future__ import annotations

import os
import socket
import threading

__all__ = ["owner", "alive", "watch", "POLL_SECONDS"]

#: How often a worker looks for its owner.
POLL_SECONDS = 1.0

_watched: set = set()
_lock = threading.Lock()


def _start_token(pid: int) -> str:
    """When process ``pid`` started (Linux: /proc/PID/stat field 22), or "" if unknown.

    A pid alone could be reused by a new process after the owner's death.
    """
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as fh:
            return fh.read().rsplit(")", 1)[1].split()[19]
    except (OSError, IndexError):
        return ""


def owner() -> tuple[str, int, str]:
    """This process, as a worker can recognise it: (host name, pid, start token)."""
    pid = os.getpid()
    return socket.gethostname(), pid, _start_token(pid)


def alive(who: tuple[str, int, str]) -> bool:
    """Whether the process ``who`` (from :func:`owner`) still runs; True when it cannot tell
    (another machine)."""
    host, pid, token = who
    if host != socket.gethostname():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:     # exists, another user's: not ours
        return False
    return _start_token(pid) == token


def watch(who: tuple[str, int, str] | None) -> None:
    """Exit this process (status 1) soon after ``who`` has gone (no-op for None or itself).

    One daemon thread per owner and process, polling every :data:`POLL_SECONDS`.
    """
    if who is None or (who[0] == socket.gethostname() and who[1] == os.getpid()):
        return
    with _lock:
        if who in _watched:
            return
        _watched.add(who)
    if not alive(who):
        os._exit(1)
    threading.Thread(target=_poll, args=(who,), daemon=True, name="morphoshell-lifeline").start()


def _poll(who) -> None:
    import time

    while alive(who):
        time.sleep(POLL_SECONDS)
    os._exit(1)
