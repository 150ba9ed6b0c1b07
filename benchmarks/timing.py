"""Wall and CPU time of one call, for the benchmark scripts in this folder."""

from __future__ import annotations

import resource
import time


def cpu_seconds() -> float:
    """CPU time of this process and of its finished child processes (user + system, all threads)."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + children.ru_utime + children.ru_stime


def timed(fn):
    """Call ``fn()``; return (result, wall seconds, CPU seconds including worker processes)."""
    start, cpu = time.perf_counter(), cpu_seconds()
    result = fn()
    return result, time.perf_counter() - start, cpu_seconds() - cpu
