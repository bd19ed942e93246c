"""The preload of a local cluster's worker processes (`dask_setup`, run by
`distributed` when the worker starts, before any task).

- Ctrl-C is the batch's to handle: a terminal sends SIGINT to every process of
  the foreground group, workers included; the workers ignore it, and the batch
  closes the cluster (a worker's half-done record stays a temporary folder).
- Each worker runs on its own share of the cores (`THREADS_ENV` cores, by the
  worker's number), set before JAX starts its backend: XLA:CPU sizes its thread pool
  by the cores the process may run on (its affinity), and the diagnosis runs as many
  refits at once as it has cores (`jaxhyst._threads.host_cores`).
"""

import os
import signal
import threading


THREADS_ENV = "JAXHYST_BATCH_THREADS"
"""Set on a local cluster's workers: the cores each worker may use."""


def pin_cores(index: int, threads: int) -> list[int]:
    """Restrict this process to `threads` cores, the `index`-th share of the cores
    it may run on (wrapping around when there are more workers than shares).
    Returns the cores chosen (none where the platform has no affinity)."""
    if not hasattr(os, "sched_setaffinity"):
        return []
    cores = sorted(os.sched_getaffinity(0))
    count = min(threads, len(cores))
    start = (index * count) % len(cores)
    chosen = [cores[(start + k) % len(cores)] for k in range(count)]
    os.sched_setaffinity(0, chosen)
    return chosen


def dask_setup(worker) -> None:
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    threads = os.environ.get(THREADS_ENV)
    try:
        index = int(worker.name)
    except (TypeError, ValueError):
        return
    if threads:
        pin_cores(index, int(threads))
