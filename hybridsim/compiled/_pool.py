"""The threads and memory of a compiled batch: the thread count, the worker pool, the
output pools (pages the batch never writes are never touched) and the Ctrl-C watch.
"""
from __future__ import annotations

import concurrent.futures
import math
import mmap
import os
import threading

import numpy as np


def _threads(parallel, rows, heavy=False):
    """How many threads run a batch of ``rows``: numba's thread count
    (``NUMBA_NUM_THREADS``, or ``numba.set_num_threads`` where numba's threads
    were started), at most one per 8 rows (one per row for ``heavy`` runs,
    long enough to pay a thread's handoff). numba's threading layer is not
    started here (``numba.get_num_threads`` would start it)."""
    if not parallel:
        return 1
    import numba
    from numba.np.ufunc import parallel as nb_parallel
    if getattr(nb_parallel, "_is_initialized", False):
        nt = numba.get_num_threads()
    else:
        nt = numba.config.NUMBA_NUM_THREADS
    return max(1, min(nt, os.cpu_count() or 1, rows if heavy else rows // 8))


#: the batch kernels' worker threads, kept between batches (starting two
#: threads and joining them took about 0.2 ms a chunk); made on first use and
#: forgotten in a forked child (its threads do not exist there)
_POOL = []
_POOL_LOCK = threading.Lock()


def _untouched(shape, dtype=np.float64):
    """An uninitialised array for a batch's sample pool, on fresh pages without
    numpy's huge-page advice.

    numpy advises huge pages for arrays of 4 MiB and more; where the kernel
    compacts memory to make them at the first write (Linux's default THP
    ``defrag`` policy for advised memory), a 100,000-ball batch spent up to
    0.9 s of system time in it, against 0.1-0.18 s on ordinary pages. Pages
    the batch never writes are never made; the memory is returned when the
    last view of it (a pooled arc's) is gone. (No map on Windows: numpy's.)"""
    nbytes = math.prod(shape) * np.dtype(dtype).itemsize
    if nbytes < (4 << 20) or not hasattr(mmap, "MAP_ANONYMOUS"):
        return np.empty(shape, dtype)
    buf = mmap.mmap(-1, nbytes, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    return np.frombuffer(buf, dtype).reshape(shape)


def _cut(a, used):
    """The first ``used`` rows of a pool array from :func:`_untouched`: numpy's
    own cut in place (no copy, the tail freed), the mapped one as a view (its
    tail never written, so never made)."""
    if a.flags.owndata:
        a.resize((used,) + a.shape[1:], refcheck=False)
        return a
    return a[:used]


def _forget_pool():
    _POOL.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pool)


def _workers(threads):
    """The worker pool, with room for ``threads`` tasks at once."""
    with _POOL_LOCK:
        if not _POOL or _POOL[0][1] < threads:
            if _POOL:
                _POOL.pop()[0].shutdown(wait=False)
            size = max(threads, os.cpu_count() or 1)
            _POOL.append((concurrent.futures.ThreadPoolExecutor(
                size, thread_name_prefix="hybridsim-compiled-batch"), size))
        return _POOL[0][0]


def _interruptible(fn, args, stop, threads=1):
    """Call a GIL-free batch kernel in ``threads`` worker threads (each takes
    rows from the batch's shared counter) so that Ctrl-C stops it: the
    calling thread waits and, on KeyboardInterrupt, sets ``stop[0]`` (every
    run reads it at each step and ends ``CANCELED``). Returns
    ``interrupted``. Off the main thread (no signals arrive there) one
    thread's batch runs in the calling thread itself, with the GIL released
    (a handoff to a worker and back costs about 150 us). The workers are
    Python threads kept between batches (:func:`_workers`), not a numba
    threading layer."""
    if threads == 1 and threading.current_thread() is not threading.main_thread():
        fn(*args)
        return False
    futures = [_workers(threads).submit(fn, *args) for _ in range(threads)]
    interrupted = False
    errors = []
    for fut in futures:
        while True:
            try:
                err = fut.exception()
                break
            except KeyboardInterrupt:
                stop[0] = 1
                interrupted = True
        if err is not None:
            errors.append(err)
    if errors:
        raise errors[0]
    return interrupted
