"""One BLAS thread while sensorplan computes.

The package's dense algebra runs on small matrices (tens to a few hundred
parameters), where multi-threaded BLAS only adds synchronisation overhead
and, on a busy machine, stalls: studies/benchmarks/bench_inversion.py
measured the same inversion 13x slower with the default threads than with
one.  Public entry points are wrapped so that BLAS uses one thread for the
duration of the call (nested calls share one limit); the previous setting
is restored afterwards.

Finding the loaded BLAS libraries costs about a millisecond (threadpoolctl
walks the process's shared objects), a few per cent of a verification
scenario; the controller that found them is kept and found again only when
a module has been imported since (a BLAS is loaded by importing an extension
module).
"""

import functools
import sys
import threading

from threadpoolctl import ThreadpoolController

__all__ = ["single_threaded"]

_lock = threading.Lock()
_depth = 0
_limiter = None
_controller = None  # (ThreadpoolController, len(sys.modules) when it looked)


def _blas_controller():
    """The ThreadpoolController of the loaded libraries, found again after new imports."""
    global _controller
    if _controller is None or _controller[1] != len(sys.modules):
        _controller = (ThreadpoolController(), len(sys.modules))
    return _controller[0]


def single_threaded(func):
    """Decorator: run ``func`` with BLAS limited to one thread."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        global _depth, _limiter
        with _lock:
            if _depth == 0:
                _limiter = _blas_controller().limit(limits=1, user_api="blas")
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
