"""Where independent pieces of work run: here, a process pool, or a Dask cluster.

:func:`executor_for` turns ``workers`` / ``scheduler`` into a
``concurrent.futures.Executor`` (None: run in this process), and
:func:`map_ordered` runs a function over items on it, in chunks, and
returns the results in submission order, whichever worker ran what.
Reproducibility is the caller's part: every item must carry its own seed.
:class:`TaskGraph` runs tasks that take other tasks' results as arguments:
on Dask all of them are submitted at once as one graph (shared read-only
inputs scattered once to every worker), elsewhere each runs as soon as
its inputs are ready.

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

__all__ = ["executor_for", "map_ordered", "worker_count", "TaskGraph", "DASK_HINT"]

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
                since = self.check_workers(since)

    def check_workers(self, since):
        """The time since which the cluster has had no worker (None: it has some); fails past ``timeout``."""
        try:
            n = self.n_workers
        except (OSError, TimeoutError) as exc:
            raise ExecutorError(f"lost the Dask scheduler at {self.address} ({' '.join(str(exc).split())}); "
                                "is it still running?") from None
        if n:
            return None
        since = time.monotonic() if since is None else since
        if time.monotonic() - since > self.timeout:
            raise ExecutorError(f"the Dask scheduler at {self.address} has had no worker for "
                                f"{self.timeout:g} s; start some with 'dask worker {self.address}'")
        return since

    def shutdown(self, wait=True, *, cancel_futures=False):
        self._inner.shutdown(wait=wait)


def _import_distributed(name):
    try:
        import distributed
    except ImportError:
        raise ConfigError(f"The '{name}' option needs Dask, which is not installed; {DASK_HINT}") from None
    return distributed


def _local_cluster(distributed, workers):
    """A LocalCluster of ``workers`` single-threaded processes, set up for small dense numerical tasks.

    Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers, which turns off
    glibc's adaptive mmap threshold: every temporary array over 128 kB is then
    mapped and unmapped anew, and a verification scenario costs about a third
    more CPU on a worker than in this process; it is left unset here, and the
    workers' sampling profiler is off.  No dashboard; the scheduler's HTTP
    server on a free local port (8787 may be taken).
    """
    import dask

    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
                          "distributed.worker.profile.enabled": False}):
        return distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                        dashboard_address=None, silence_logs=logging.ERROR,
                                        scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"})


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
                cluster = _local_cluster(distributed, workers)
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


class _Ref:
    """A node of a :class:`TaskGraph` (its position in the graph)."""

    __slots__ = ("index",)

    def __init__(self, index):
        self.index = index


def _refs_in(args):
    """The :class:`_Ref` among ``args`` (top level, or inside a list or tuple)."""
    for a in args:
        if isinstance(a, _Ref):
            yield a
        elif isinstance(a, (list, tuple)):
            yield from (b for b in a if isinstance(b, _Ref))


def _resolve(args, value_of):
    """``args`` with every :class:`_Ref` (top level, or inside a list or tuple) replaced by ``value_of(ref)``."""
    out = []
    for a in args:
        if isinstance(a, _Ref):
            out.append(value_of(a))
        elif isinstance(a, (list, tuple)):
            out.append(type(a)(value_of(b) if isinstance(b, _Ref) else b for b in a))
        else:
            out.append(a)
    return out


class TaskGraph:
    """Tasks whose arguments may be other tasks' results, run on an executor; results by node.

    ``constant(value)`` is a shared read-only input (on Dask scattered once to
    every worker), ``task(fn, *args, weight=w)`` a call of a module-level
    function whose arguments may be nodes (also inside a list or tuple), and
    :meth:`run` runs everything: on Dask all tasks are submitted at once as
    one graph (the scheduler starts each when its inputs exist, no round trip
    through this process), on another executor each task is submitted as
    soon as its inputs are done, and without an executor they run here in
    the order they were added.  ``progress(done, total)`` is called as tasks
    finish, in units of their ``weight`` (tasks of weight 0 are not counted).
    Results do not depend on where the tasks ran.
    """

    def __init__(self, executor: Executor | None):
        self.executor = executor
        self._nodes: list = []  # (fn, args, weight); fn None for a constant (args = (value,))
        self._values: dict = {}

    def constant(self, value) -> _Ref:
        """A node holding ``value``, an input shared by the tasks that take it (not copied per task on Dask)."""
        self._nodes.append((None, (value,), 0))
        return _Ref(len(self._nodes) - 1)

    def task(self, fn: Callable, *args, weight: int = 0) -> _Ref:
        """A node ``fn(*args)``, nodes among ``args`` replaced by their values; ``weight``: its progress units."""
        self._nodes.append((fn, args, int(weight)))
        return _Ref(len(self._nodes) - 1)

    def result(self, ref: _Ref):
        """The value of a node (after :meth:`run`)."""
        return self._values[ref.index]

    def run(self, progress: Callable[[int, int], None] | None = None) -> None:
        """Run every task (see the class); an error raised by a task propagates, a dead worker is an ExecutorError."""
        total = sum(w for _, _, w in self._nodes)
        done = [0]

        def finished(i, value):
            self._values[i] = value
            weight = self._nodes[i][2]
            if weight and progress is not None:
                done[0] += weight
                progress(done[0], total)

        try:
            if self.executor is None:
                for i, (fn, args, _) in enumerate(self._nodes):
                    finished(i, args[0] if fn is None else fn(*_resolve(args, self.result)))
            elif isinstance(self.executor, DaskExecutor):
                self._run_dask(finished)
            else:
                self._run_pool(finished)
        except _death_errors() as exc:
            raise ExecutorError(f"a worker died while running the work ({type(exc).__name__}: "
                                f"{' '.join(str(exc).split())[:200]}); out of memory?") from None

    def _run_dask(self, finished):
        import distributed

        runner = self.executor
        since = runner.check_workers(None)
        while since is not None:  # scattering needs a worker: wait for one (a clear error after the timeout)
            time.sleep(0.2)
            since = runner.check_workers(since)
        futures: dict = {}
        for i, (fn, args, _) in enumerate(self._nodes):  # one submission of the whole graph
            if fn is None:
                futures[i] = runner.client.scatter(args[0], broadcast=True, hash=False)
            else:
                futures[i] = runner.client.submit(fn, *_resolve(args, lambda r: futures[r.index]), pure=False)
        tasks = {futures[i].key: i for i, (fn, _, _) in enumerate(self._nodes) if fn is not None}
        for i, (fn, args, _) in enumerate(self._nodes):
            if fn is None:
                self._values[i] = args[0]
        pending = [futures[i] for i in tasks.values()]
        try:
            while pending:
                ready = [f for f in pending if f.done()]
                if not ready:  # wait on one (the workers checked every _POLL_S), then take all that are done
                    try:
                        pending[0].result(timeout=_POLL_S)
                    except (concurrent.futures.TimeoutError, TimeoutError, distributed.TimeoutError):
                        since = runner.check_workers(since)
                        continue
                    ready = [f for f in pending if f.done()]
                since = None
                for future in ready:
                    finished(tasks[future.key], future.result())
                taken = {f.key for f in ready}
                pending = [f for f in pending if f.key not in taken]
        finally:
            for future in futures.values():
                future.cancel()

    def _run_pool(self, finished):
        nodes, waiting = self._nodes, {}
        for i, (fn, args, _) in enumerate(nodes):
            if fn is None:
                finished(i, args[0])
            else:
                waiting[i] = {r.index for r in _refs_in(args)}
        running: dict = {}
        try:
            while waiting or running:
                for i in [i for i, deps in waiting.items() if deps <= self._values.keys()]:
                    fn, args, _ = nodes[i]
                    running[self.executor.submit(fn, *_resolve(args, self.result))] = i
                    del waiting[i]
                ready, _ = concurrent.futures.wait(running, return_when=concurrent.futures.FIRST_COMPLETED)
                for future in sorted(ready, key=running.get):
                    finished(running.pop(future), future.result())
        finally:
            for future in running:
                future.cancel()
