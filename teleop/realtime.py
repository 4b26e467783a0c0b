"""Real-time scheduling for the processes of a control loop (the slave, the link, the render loop).

On a shared or busy machine a process at normal priority waits for a CPU for tens to
hundreds of milliseconds; at 1 kHz that is a hundred samples refused by a full queue or
dropped as stale. Under SCHED_FIFO the loop runs as soon as it is ready, ahead of every
normal process (docs/teleop.md has the figures). Like ur-rtde's ``rt_priority``, this is a
request: without the permission it is refused and the process runs on at normal priority,
saying so once.

Call it before the process starts its threads (ZeroMQ's context, PyBullet): Linux applies
the policy to the calling thread, and threads started later inherit it.
"""

from __future__ import annotations

import logging
import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

log = logging.getLogger(__name__)

HOW_TO_PERMIT = ("run as root, grant CAP_SYS_NICE (setcap cap_sys_nice+ep on the Python "
                 "binary) or allow it in /etc/security/limits.conf (@group - rtprio 99)")


def request_realtime(priority: int, cpu: int | None = None) -> str:
    """Ask for SCHED_FIFO at ``priority`` (1-99; 0 leaves scheduling alone).

    ``cpu`` pins the process to that CPU (negative counts from the last one) as the render
    loop does, so it never migrates. Returns what the process got, e.g. ``"SCHED_FIFO 50"``
    or ``"normal (...why...)"``; never raises for a refused request.
    """
    if priority == 0:
        return "normal"
    if not 1 <= priority <= 99:
        raise ValueError(f"real-time priority must be 0 (off) or 1-99, got {priority}")
    if not hasattr(os, "sched_setscheduler"):
        return "normal (SCHED_FIFO is not available on this system)"
    try:
        if cpu is not None:
            cpus = sorted(os.sched_getaffinity(0))
            if len(cpus) > 1:
                os.sched_setaffinity(0, {cpus[cpu]})
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        why = f"normal (SCHED_FIFO {priority} not permitted: {HOW_TO_PERMIT})"
        log.warning("real-time priority refused, running at %s", why)
        return why
    except OSError as e:
        why = f"normal (SCHED_FIFO {priority} refused: {e})"
        log.warning("real-time priority refused, running at %s", why)
        return why
    return f"SCHED_FIFO {priority}"


def _thread_ids() -> list[int]:
    try:
        return [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:  # no /proc: the calling thread only
        return [threading.get_native_id()]


def _set_policy(tid: int, policy: int, param: os.sched_param) -> None:
    try:
        os.sched_setscheduler(tid, policy, param)
    except (ProcessLookupError, PermissionError):
        pass  # the thread ended meanwhile, or we may not lower it: nothing to undo


@contextmanager
def realtime_scheduling(priority: int, cpu: int | None = None) -> Iterator[str]:
    """The whole process on SCHED_FIFO for a block (``request_realtime`` for the calling
    thread, then every other thread: ZeroMQ's I/O threads may predate the block), then
    every thread as it was, and those started inside on the caller's former policy: a
    command run inside another program (a test, a notebook) must not leave it, or the
    processes it starts later, on SCHED_FIFO. ``cpu`` pins the calling thread meanwhile."""
    if priority == 0 or not hasattr(os, "sched_getscheduler"):
        yield request_realtime(priority, cpu)
        return
    before = {}
    for tid in _thread_ids():
        try:
            before[tid] = (os.sched_getscheduler(tid), os.sched_getparam(tid))
        except ProcessLookupError:
            pass
    caller = (os.sched_getscheduler(0), os.sched_getparam(0))
    cpus = os.sched_getaffinity(0)
    got = request_realtime(priority, cpu)
    fifo = got.startswith("SCHED_FIFO")
    try:
        if fifo:
            for tid in before:
                _set_policy(tid, os.SCHED_FIFO, os.sched_param(priority))
        yield got
    finally:
        if fifo:
            me = threading.get_native_id()
            for tid in _thread_ids():
                if tid != me:
                    _set_policy(tid, *before.get(tid, caller))
            os.sched_setscheduler(0, *caller)
        if cpu is not None:
            os.sched_setaffinity(0, cpus)
