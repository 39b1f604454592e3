"""One BLAS thread while sensorplan computes.

The package's dense algebra runs on small matrices (tens to a few hundred
parameters), where multi-threaded BLAS only adds synchronisation overhead
and, on a busy machine, stalls: studies/benchmarks/bench_inversion.py
measured the same inversion 13x slower with the default threads than with
one.  Public entry points are wrapped so that BLAS uses one thread for the
duration of the call (nested calls share one limit); the previous setting
is restored afterwards.
"""

import functools
import threading

from threadpoolctl import threadpool_limits

__all__ = ["single_threaded"]

_lock = threading.Lock()
_depth = 0
_limiter = None


def single_threaded(func):
    """Decorator: run ``func`` with BLAS limited to one thread."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        global _depth, _limiter
        with _lock:
            if _depth == 0:
                _limiter = threadpool_limits(limits=1, user_api="blas")
            _depth += 1
        try:
            return func(*args, **kwargs)
        finally:
            with _lock:
                _depth -= 1
                if _depth == 0 and _limiter is not None:
                    _limiter.restore_original_limits()
                    _limiter = None

    return wrapper
