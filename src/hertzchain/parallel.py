"""Independent tasks run here or on a cluster: sweeps' chunks, design generations, fit bootstraps.

One narrow call joins the rooms that farm work out (:mod:`hertzchain.sweep`,
:mod:`hertzchain.design`, :mod:`hertzchain.lab`) to whatever runs it: :func:`results_as_completed`
(each result as soon as it is ready) and :func:`results_in_order`. The ``client`` is None (here,
one task after the other), a Dask ``distributed.Client`` (worker processes on this machine or
on others), a ``concurrent.futures.Executor``, anything with ``submit`` and ``gather``, or
anything with ``map``.

What makes a cluster of processes and machines work:

- a task is a module-level function and a plain dataclass of NumPy arrays and numbers (pickled by
  Dask to the worker); its result is arrays again, sent back to the client, which alone writes
  files. Nothing on a worker touches the client's files, or a lock of the client's process;
- tasks are submitted a few at a time (:data:`IN_FLIGHT_PER_THREAD` per worker thread), so a
  million-member sweep never holds its ten thousand chunks in the scheduler's memory;
- a worker that dies (killed, out of memory, its machine gone) costs only its running task: the
  scheduler hands it to another worker (up to ``distributed.scheduler.allowed-failures`` times,
  then :class:`ClusterError`). A task's result depends on the task alone, so the rerun gives the
  same bytes;
- an exception raised by a task (a user error, a diverged run) is raised here, as it is.
"""

from __future__ import annotations

import itertools
import os
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Iterable, Iterator

from .errors import ConfigError, HertzchainError


__all__ = ["usable_cores", "on_threads", "connect", "check_address", "results_as_completed", "results_in_order", "ClusterError",
           "IN_FLIGHT_PER_THREAD"]

#: Tasks kept submitted per worker thread: enough to keep every worker busy while results travel
#: back, few enough that the scheduler and the client hold only a handful of tasks.
IN_FLIGHT_PER_THREAD = 2
#: Seconds between two looks at a Dask cluster's finished tasks.
POLL_S = 0.05


def usable_cores() -> int:
    """The cores this process may run on: its CPU affinity (``os.cpu_count()`` where the platform
    has none), at least 1."""
    try:
        return max(len(os.sched_getaffinity(0)), 1)
    except (AttributeError, OSError):  # not on Linux
        return max(os.cpu_count() or 1, 1)


def on_threads(fn: Callable, shares: list, *args) -> None:
    """``fn(share, *args)`` for every share, each on a thread of its own (one share: here), for
    ``fn`` a compiled loop that releases the GIL (``nogil``) over the items of its share: the
    batched engines' members, the pulse fits' rows. Returns when every share is done; the first
    error a share raised is raised here."""
    if len(shares) <= 1:
        for share in shares:
            fn(share, *args)
        return
    with ThreadPoolExecutor(len(shares), thread_name_prefix="hertzchain") as pool:
        for done in [pool.submit(fn, share, *args) for share in shares]:
            done.result()

class ClusterError(HertzchainError):
    """The Dask cluster lost a task for good (its workers died every time it ran)."""


#: Seconds to reach a scheduler: a scheduler on a network answers in well under a second.
CONNECT_TIMEOUT_S = 10.0
#: Seconds to wait for a first worker of a cluster that has none (it may be starting).
WORKER_WAIT_S = 30.0


def check_address(address: str) -> str:
    """The scheduler address ``address`` as ``tcp://HOST:PORT``, or a ConfigError naming ``--scheduler``.

    hertzchain speaks plain TCP to a Dask scheduler (``tcp://HOST:PORT`` or ``HOST:PORT``, as
    ``dask scheduler`` prints it; ``inproc://`` names a scheduler in this very process, a
    ``LocalCluster(processes=False)``): TLS needs certificates and UCX a network stack that no
    option here configures, so those (and any other scheme) are refused at once, not tried.

    Parameters
    ----------
    address : str
        What the user gave to ``--scheduler``.

    Returns
    -------
    str
        The address with its scheme (``tcp://`` or ``inproc://``).
    """
    text = address.strip()
    scheme, sep, rest = text.partition("://")
    if not sep:
        scheme, rest = "tcp", text
    if scheme == "inproc" and rest:
        return text
    if scheme.lower() != "tcp":
        why = {"tls": "TLS needs certificates, which --scheduler does not take",
               "ucx": "UCX needs a network stack that --scheduler does not configure"}.get(scheme.lower(),
                                                                                             "an unknown scheme")
        raise ConfigError("--scheduler", f"{address!r}: {scheme}:// is not supported ({why}); give the scheduler's "
                          "plain TCP address, tcp://HOST:PORT, as 'dask scheduler' prints it")
    host, colon, port = rest.rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not colon or not host or not port.isdigit() or not 1 <= int(port) <= 65535 or any(c in host for c in "/ @"):
        raise ConfigError("--scheduler", f"{address!r} is not a scheduler address; give tcp://HOST:PORT (a host "
                          "name or IP address, and a port from 1 to 65535), as 'dask scheduler' prints it")
    return f"tcp://{rest}"


def connect(address: str, timeout: float | str = CONNECT_TIMEOUT_S, worker_wait: float = WORKER_WAIT_S,
            notify: Callable[[str], None] | None = None):
    """A Dask ``distributed.Client`` connected to the scheduler at ``address``, with a worker.

    The client is not made Dask's default scheduler: nothing else in this process (xarray writing
    a file, a ``.compute()``) is sent to the cluster by accident. An address of another scheme
    than TCP is refused before anything is tried (:func:`check_address`); a scheduler that does
    not answer within ``timeout`` seconds is an error; a cluster without a worker is waited for
    ``worker_wait`` seconds (saying so through ``notify``), then an error: a task sent there
    would wait forever.

    Parameters
    ----------
    address : str
        The scheduler's address, e.g. ``tcp://10.0.0.5:8786`` (``dask scheduler`` prints it).
    timeout : float or str
        Seconds to try to connect (or a Dask time string, ``"5s"``).
    worker_wait : float
        Seconds to wait for a first worker when the cluster has none.
    notify : callable or None
        Called with a one-line message when the wait for a worker begins (the CLI prints it).

    Returns
    -------
    distributed.Client
        Connected; close it when done (``client.close()``).

    Raises
    ------
    ConfigError
        (field ``--scheduler``) for an unsupported address, when no scheduler answers at
        ``address``, or when no worker joins it in time.
    """
    url = check_address(address)  # a bad address is said first, whatever is installed
    from .extras import require

    require("cluster", "--scheduler", ("distributed",))
    try:
        from distributed import Client

        client = Client(url, timeout=timeout if isinstance(timeout, str) else f"{timeout}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        raise ConfigError("--scheduler", f"cannot connect to the Dask scheduler at {address!r}: {exc}; start one "
                          "with 'dask scheduler' and give the address it prints") from None
    try:
        if not client.scheduler_info().get("workers"):
            if notify is not None:
                notify(f"the Dask scheduler at {address} has no worker; waiting up to {worker_wait:g} s for one "
                       f"(start workers with 'dask worker {url}')")
            client.wait_for_workers(1, timeout=worker_wait)
    except (OSError, TimeoutError) as exc:
        client.close()
        raise ConfigError("--scheduler", f"no worker joined the Dask cluster at {address!r} within {worker_wait:g} s "
                          f"({type(exc).__name__}); start workers with 'dask worker {url}' and run again") from None
    return client


def _is_dask(client) -> bool:
    try:
        import distributed
    except ImportError:  # the [cluster] extra is not installed: no client can be a Dask one
        return False
    return isinstance(client, distributed.Client)


def _dask_threads(client) -> int:
    try:
        return max(1, sum(client.nthreads().values()))
    except Exception:  # noqa: BLE001 - a scheduler that does not answer now: the first results will tell
        return 1


def worker_threads(client) -> int:
    """Threads that run tasks sent to ``client``: a Dask cluster's worker threads, an executor's
    workers (1 when it does not say), for projections of the time a run will take there."""
    if _is_dask(client):
        return _dask_threads(client)
    return max(int(getattr(client, "_max_workers", 1) or 1), 1)


def results_as_completed(client, fn: Callable[[Any], Any], tasks: Iterable) -> Iterator:
    """Yield ``fn(task)`` for every task, each as soon as it is available (in no set order).

    Parameters
    ----------
    client : object
        None (here, in order), a Dask ``distributed.Client``, a ``concurrent.futures.Executor``,
        anything with ``submit`` and ``gather``, or anything with ``map``.
    fn : callable
        A module-level function (it is pickled by reference to the workers).
    tasks : iterable
        The tasks, consumed lazily: only the submitted ones are held.

    Yields
    ------
    object
        ``fn(task)`` of each task.

    Raises
    ------
    ClusterError
        A Dask task whose workers died every time it ran.
    ConfigError
        A ``client`` that can run nothing.
    """
    if client is None:
        for t in tasks:
            yield fn(t)  # nothing kept here: a result is freed once the caller lets it go
        return
    import concurrent.futures as cf

    if _is_dask(client):
        yield from _dask_results(client, fn, iter(tasks))
    elif isinstance(client, cf.Executor):
        it = iter(tasks)
        window = max(2, IN_FLIGHT_PER_THREAD * (getattr(client, "_max_workers", 1) or 1))
        pending = {client.submit(fn, t) for t in itertools.islice(it, window)}
        try:
            while pending:
                done, pending = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
                for fut in done:
                    nxt = next(it, _END)
                    if nxt is not _END:
                        pending.add(client.submit(fn, nxt))
                    yield fut.result()
        finally:
            for f in pending:
                f.cancel()
    elif hasattr(client, "submit") and hasattr(client, "gather"):
        import collections

        it = iter(tasks)
        queue = collections.deque(client.submit(fn, t) for t in itertools.islice(it, 2 * IN_FLIGHT_PER_THREAD))
        while queue:  # in order, a few submitted ahead
            nxt = next(it, _END)
            if nxt is not _END:
                queue.append(client.submit(fn, nxt))
            yield client.gather(queue.popleft())
    elif hasattr(client, "map"):
        yield from client.map(fn, tasks)
    else:
        raise ConfigError("client", f"must have submit/gather or map (a Dask client, an executor), "
                          f"got {type(client).__name__}")


_END = object()


def _dask_results(client, fn, it: Iterator) -> Iterator:
    """:func:`results_as_completed` on a Dask client: a window of submitted tasks, refilled as
    results come back; every unfinished task cancelled when the caller stops early.

    The wait polls (:data:`POLL_S`) so that a Ctrl-C swallowed while waiting is raised
    (:func:`hertzchain.interrupts.check`) without waiting for the next result.
    """
    import time

    import distributed

    from .interrupts import check

    window = max(2, IN_FLIGHT_PER_THREAD * _dask_threads(client))
    # pure=False: each submission is a new task (Dask would otherwise share equal tasks by key).
    pending = distributed.as_completed([client.submit(fn, t, pure=False) for t in itertools.islice(it, window)],
                                       loop=client.loop)
    try:
        while not pending.is_empty():
            batch = pending.next_batch(block=False)
            if not batch:
                check()
                time.sleep(POLL_S)
                continue
            for fut in batch:
                try:
                    result = fut.result()
                except distributed.KilledWorker as exc:
                    raise ClusterError(f"a task was lost: every Dask worker that ran it died ({exc}); a worker "
                                       "killed for memory is the usual cause: give the workers more memory "
                                       "(dask worker --memory-limit) or make the tasks smaller (sweep.chunk_size, "
                                       "design.chunk_size)") from None
                fut.release()
                nxt = next(it, _END)
                if nxt is not _END:
                    pending.add(client.submit(fn, nxt, pure=False))
                yield result
                del result  # not held here while the next one is awaited
    finally:  # stopped early (an error, Ctrl-C): leave no work running on the cluster
        left = list(pending.futures)
        if left:
            client.cancel(left)


def results_in_order(client, fn: Callable[[Any], Any], tasks: list) -> list:
    """``[fn(t) for t in tasks]``, computed by ``client`` (see :func:`results_as_completed`).

    Parameters
    ----------
    client : object
        As for :func:`results_as_completed`.
    fn : callable
        A module-level function.
    tasks : list
        The tasks.

    Returns
    -------
    list
        The results, in the order of ``tasks``.
    """
    if client is None:
        return [fn(t) for t in tasks]
    got = dict(results_as_completed(client, _Indexed(fn), list(enumerate(tasks))))
    return [got[i] for i in range(len(tasks))]


class _Indexed:
    """``fn`` applied to ``(i, task)``, returning ``(i, fn(task))`` (picklable: a class, not a closure)."""

    def __init__(self, fn: Callable[[Any], Any]) -> None:
        self.fn = fn

    def __call__(self, item: tuple[int, Any]) -> tuple[int, Any]:
        return item[0], self.fn(item[1])
