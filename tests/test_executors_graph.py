"""TaskGraph: tasks taking other tasks' results, run here, on a pool, or on Dask as one submission.

References: the same expressions evaluated directly in Python (operator calls), and for the study and
the verification the in-process run (workers=1), which shares no scheduling code with the graph on Dask.
"""

import json
import operator
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from sensorplan import design_study, example_case, verify_layouts
from sensorplan._executors import TaskGraph, executor_for



def has_dask():
    try:
        import distributed  # noqa: F401
    except ImportError:
        return False
    return True


needs_dask = pytest.mark.skipif(not has_dask(), reason="the dask extra is not installed")


def _graph(executor):
    """10 -> a = 10 + 1, b = a * 2, c = sum([a, b]); weights 1, 2, 3 (progress units)."""
    graph = TaskGraph(executor)
    ten = graph.constant(10)
    a = graph.task(operator.add, ten, 1, weight=1)
    b = graph.task(operator.mul, a, 2, weight=2)
    c = graph.task(sum, [a, b], weight=3)
    return graph, (a, b, c)


def _check(executor):
    graph, nodes = _graph(executor)
    seen = []
    graph.run(lambda done, total: seen.append((done, total)))
    assert [graph.result(n) for n in nodes] == [11, 22, 33]  # reference: 10 + 1, 11 * 2, 11 + 22
    assert seen[-1] == (6, 6) and all(t == 6 for _, t in seen)
    assert [d for d, _ in seen] == sorted(d for d, _ in seen)


def test_graph_runs_in_process_in_order_of_addition():
    _check(None)
    graph, (a, b, c) = _graph(None)
    seen = []
    graph.run(lambda done, total: seen.append(done))
    assert seen == [1, 3, 6]  # each task counted as it finishes, in the order added


def test_graph_on_a_pool_starts_tasks_when_their_inputs_are_done():
    with ThreadPoolExecutor(2) as pool:
        _check(pool)


def test_an_error_in_a_task_propagates_unchanged():
    graph = TaskGraph(None)
    graph.task(operator.truediv, 1.0, 0.0)
    with pytest.raises(ZeroDivisionError):
        graph.run()
    with ThreadPoolExecutor(2) as pool:
        graph = TaskGraph(pool)
        graph.task(time.sleep, 0.01)
        graph.task(operator.truediv, 1.0, 0.0)
        with pytest.raises(ZeroDivisionError):
            graph.run()


@needs_dask
@pytest.mark.slow
def test_graph_on_a_local_cluster_gives_the_same_results():
    with executor_for(2, "local") as cluster:
        _check(cluster)
        graph = TaskGraph(cluster)
        graph.task(operator.truediv, 1.0, 0.0)
        with pytest.raises(ZeroDivisionError):
            graph.run()


STUDY = dict(criteria=["D", "A"], counts=2, baselines=["equally_spaced"], n_scenarios=2, n_controls=1,
             n_crossings=3, spacing=2.0, seed=5)


@needs_dask
@pytest.mark.slow
def test_study_as_one_graph_on_a_local_cluster_equals_one_process():
    # two criteria: the equally spaced baseline is the same layout for both and is verified once
    case = example_case("simply-supported")
    one = design_study([case], **STUDY)
    seen = []
    cluster = design_study([case], workers=2, scheduler="local", progress=lambda d, t: seen.append((d, t)), **STUDY)
    assert json.dumps(cluster.to_dict(), sort_keys=True) == json.dumps(one.to_dict(), sort_keys=True)
    assert seen and seen[-1][0] == seen[-1][1]
    layouts = {r.layout_m for r in one.rows}
    assert len(one.verifications[case.name].layouts) == len(layouts) < len(one.rows)


@pytest.mark.slow
def test_verification_on_a_pool_equals_one_process_for_several_layouts():
    case = example_case("simply-supported")
    layouts = [[4.0, 16.0], [0.0, 10.0, 20.0], [2.0, 9.0, 18.0]]
    options = dict(n_locations=2, n_controls=2, n_crossings=3, seed=4)
    one = verify_layouts(case, layouts, **options).to_dict()
    with ThreadPoolExecutor(3) as pool:
        threads = verify_layouts(case, layouts, executor=pool, **options).to_dict()
    assert json.dumps(threads, sort_keys=True) == json.dumps(one, sort_keys=True)


def test_chunks_are_about_eight_per_worker_and_even():
    from sensorplan.verification.dispatch import chunk_count, split

    assert chunk_count(None, 92) == 92  # in process: progress after every scenario
    with ThreadPoolExecutor(2) as pool:
        assert chunk_count(pool, 92) == 16  # 8 tasks per worker: 8 each on two workers
        assert chunk_count(pool, 92, n_layouts=3) == 6  # 18 over the three layouts
        assert chunk_count(pool, 3) == 3
        assert chunk_count(pool, 10, n_layouts=40) == 1  # at least one task per layout
    runs = split(92, 16)
    assert [i for run in runs for i in run] == list(range(92))
    assert {len(run) for run in runs} == {5, 6}  # 92 = 12 x 6 + 4 x 5: no short tail task
    assert split(3, 16) == [(0,), (1,), (2,)] and split(0, 4) == [] and split(7, 1) == [tuple(range(7))]
