"""One BLAS thread inside sensorplan's entry points, the previous setting restored afterwards."""

import sys
import types

import numpy as np  # noqa: F401 - loads the BLAS the limits act on (as every computation of the package does)
import scipy.linalg  # noqa: F401
from threadpoolctl import threadpool_info, threadpool_limits

from sensorplan import _threads
from sensorplan._threads import single_threaded


def _blas_threads():
    return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]


def test_blas_runs_on_one_thread_inside_and_as_before_after():
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        inside = single_threaded(_blas_threads)()
        nested = single_threaded(lambda: single_threaded(_blas_threads)() + _blas_threads())()
        after = _blas_threads()
    assert before and inside and nested
    assert set(inside) == {1} and set(nested) == {1}
    assert after == before


def test_the_libraries_are_found_again_after_an_import(monkeypatch):
    first = _threads._blas_controller()
    assert _threads._blas_controller() is first  # kept while nothing was imported
    monkeypatch.setitem(sys.modules, "sensorplan_test_dummy_module", types.ModuleType("dummy"))
    assert _threads._blas_controller() is not first
