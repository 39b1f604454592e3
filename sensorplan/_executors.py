"""Where independent pieces of work run: here, a process pool, or a Dask cluster.

:func:`executor_for` turns ``workers`` / ``scheduler`` into a
``concurrent.futures.Executor`` (None: run in this process), and
:func:`map_ordered` runs a function over items on it, in chunks, and
returns the results in submission order, whichever worker ran what.
Reproducibility is the caller's part: every item must carry its own seed.

Dask (``dask.distributed``) is optional and imported only when a
``scheduler`` is asked for: an address such as ``tcp://127.0.0.1:8786``
(a running ``dask scheduler``), or ``"local"`` for a LocalCluster of
``workers`` single-threaded processes started here and closed afterwards.
Failures become one-line :class:`ExecutorError` messages: Dask missing, a
scheduler that does not answer within ``timeout`` seconds, workers that die
or disappear.
"""

import concurrent.futures
import logging
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, ProcessPoolExecutor
from contextlib import contextmanager

from ._errors import ConfigError, ExecutorError

__all__ = ["executor_for", "map_ordered", "worker_count", "DASK_HINT"]

DASK_HINT = "install the extra: pip install -e '.[dask]'"
_POLL_S = 2.0  # how often a Dask wait checks that the cluster still has workers


class DaskExecutor(Executor):
    """A ``concurrent.futures.Executor`` on a ``dask.distributed`` Client (tasks are never deduplicated)."""

    def __init__(self, client, address, timeout):
        self.client = client
        self.address = address
        self.timeout = float(timeout)
        self._inner = client.get_executor(pure=False)

    def submit(self, fn, /, *args, **kwargs):
        return self._inner.submit(fn, *args, **kwargs)

    @property
    def n_workers(self):
        """Threads of the cluster's workers (0 while none is connected)."""
        return int(sum(self.client.nthreads().values()))

    def wait(self, future):
        """``future.result()``, failing clearly when the cluster has had no worker for ``timeout`` seconds."""
        since = None
        while True:
            try:
                return future.result(timeout=_POLL_S)
            except concurrent.futures.TimeoutError:
                pass
            try:
                n = self.n_workers
            except (OSError, TimeoutError) as exc:
                raise ExecutorError(f"lost the Dask scheduler at {self.address} ({' '.join(str(exc).split())}); "
                                    "is it still running?") from None
            if n:
                since = None
                continue
            since = time.monotonic() if since is None else since
            if time.monotonic() - since > self.timeout:
                raise ExecutorError(f"the Dask scheduler at {self.address} has had no worker for "
                                    f"{self.timeout:g} s; start some with 'dask worker {self.address}'")

    def shutdown(self, wait=True, *, cancel_futures=False):
        self._inner.shutdown(wait=wait)


def _import_distributed(name):
    try:
        import distributed
    except ImportError:
        raise ConfigError(f"The '{name}' option needs Dask, which is not installed; {DASK_HINT}") from None
    return distributed


@contextmanager
def executor_for(workers: int = 1, scheduler: str | None = None, *, timeout: float = 10.0,
                 name: str = "scheduler") -> Iterator[Executor | None]:
    """An executor for ``workers`` processes or a Dask ``scheduler`` (None: this process), closed on exit.

    ``scheduler``: None (a process pool when ``workers > 1``), ``"local"`` (a
    LocalCluster of ``workers`` processes) or the address of a running Dask
    scheduler (its own workers are used; ``workers`` is ignored).  ``name``
    is how errors call the option (e.g. ``"--scheduler"`` on the command line).
    """
    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise ConfigError(f"The 'workers' parameter must be a positive integer. Got {workers!r} instead.")
    workers = int(workers)
    if scheduler is None:
        if workers == 1:
            yield None
            return
        pool = ProcessPoolExecutor(max_workers=workers)
        try:
            yield pool
        finally:
            pool.shutdown(cancel_futures=True)
        return
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise ConfigError(f"The '{name}' option must be a Dask scheduler address such as tcp://127.0.0.1:8786 "
                          f"or 'local'. Got {scheduler!r} instead.")
    distributed = _import_distributed(name)
    cluster = client = None
    try:
        try:
            if scheduler == "local":
                # no dashboard; the scheduler's HTTP server on a free local port (8787 may be taken)
                cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                   dashboard_address=None, silence_logs=logging.ERROR,
                                                   scheduler_kwargs={"dashboard": False,
                                                                     "dashboard_address": "127.0.0.1:0"})
                client = distributed.Client(cluster, timeout=timeout)
            else:
                client = distributed.Client(scheduler, timeout=timeout)
        except ValueError as exc:
            raise ConfigError(f"The '{name}' option {scheduler!r} is not a Dask scheduler address "
                              f"({' '.join(str(exc).split())}); give e.g. tcp://127.0.0.1:8786 or 'local'") from None
        except (OSError, TimeoutError) as exc:
            what = "a local Dask cluster could not start" if scheduler == "local" else \
                f"no Dask scheduler answered at {scheduler} within {timeout:g} s"
            raise ExecutorError(f"{name} {scheduler}: {what} ({' '.join(str(exc).split())}); start one with "
                                f"'dask scheduler' and 'dask worker ADDRESS', or use '{name} local'") from None
        yield DaskExecutor(client, scheduler if cluster is None else cluster.scheduler_address, timeout)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


def worker_count(executor: Executor | None, default: int = 1) -> int:
    """Number of parallel workers of ``executor`` (``default`` when it does not say)."""
    if executor is None:
        return 1
    if isinstance(executor, DaskExecutor):
        return max(1, executor.n_workers)
    return max(1, int(getattr(executor, "_max_workers", default) or default))


def _apply(fn, chunk):
    return [fn(item) for item in chunk]


def _death_errors() -> tuple:
    """Exceptions that mean a worker died (Dask's only when Dask is loaded)."""
    errors: list[type[BaseException]] = [concurrent.futures.BrokenExecutor]
    if "distributed" in sys.modules:
        from distributed.scheduler import KilledWorker
        errors.append(KilledWorker)
    return tuple(errors)


def map_ordered(executor: Executor | None, fn: Callable, items: Sequence, *, chunksize: int | None = None,
                progress: Callable[[int, int], None] | None = None) -> list:
    """``[fn(item) for item in items]`` on ``executor``, in chunks; results in the order of ``items``.

    ``fn`` must be a module-level function (it is pickled).  ``progress`` is
    called with (done, total) after each item.  A worker that dies raises
    :class:`ExecutorError`; an error raised by ``fn`` propagates unchanged.
    """
    items = list(items)
    total = len(items)
    out: list = []
    if executor is None:
        for item in items:
            out.append(fn(item))
            if progress is not None:
                progress(len(out), total)
        return out
    if chunksize is None:
        chunksize = max(1, total // (8 * worker_count(executor)))
    chunks = [items[i:i + chunksize] for i in range(0, total, chunksize)]
    wait = executor.wait if isinstance(executor, DaskExecutor) else (lambda f: f.result())
    futures = [executor.submit(_apply, fn, chunk) for chunk in chunks]
    try:
        for future in futures:
            for result in wait(future):
                out.append(result)
                if progress is not None:
                    progress(len(out), total)
    except _death_errors() as exc:
        raise ExecutorError(f"a worker died while running the work ({type(exc).__name__}: "
                            f"{' '.join(str(exc).split())[:200]}); out of memory?") from None
    finally:
        for future in futures:
            future.cancel()
    return out
