"""Where the verification work runs: the pilots and the scenarios of plans as one task graph.

Every layout of a :class:`~.verify.VerificationPlan` has one pilot
inversion (its result warm-starts the layout's scenarios) and its
scenarios, run in chunks so that the cost of a task (sending it, its
result) stays small against the inversions it holds.  The plan is a
shared read-only input: on Dask it is scattered once to every worker and
the tasks refer to it; the chunk tasks take the pilot's result as an
input, so the whole verification is submitted at once
(:class:`sensorplan._executors.TaskGraph`).  Every task carries its
scenario's seed, so the records do not depend on where they ran.

Owns: the tasks of a verification and their chunking.  May import: the foundations.
"""

import math

import numpy as np

from .._executors import TaskGraph, worker_count

__all__ = ["run_plans", "add_plan", "chunk_count", "split", "pilot_start", "scenario_chunk", "plan_records"]


def chunk_count(executor, n_scenarios, n_layouts=1):
    """Tasks per layout: one per scenario without an executor (progress per scenario), else about eight per
    worker over all the layouts (the tail, the last tasks that run alone, is then a small share of the work)."""
    if executor is None:
        return n_scenarios
    return max(1, min(n_scenarios, math.ceil(8 * worker_count(executor) / max(1, n_layouts))))


def split(n_scenarios, n_chunks):
    """``range(n_scenarios)`` in ``n_chunks`` runs whose sizes differ by at most one (tuples of indices)."""
    runs = np.array_split(np.arange(n_scenarios), max(1, min(n_chunks, n_scenarios)))
    return [tuple(run.tolist()) for run in runs if run.size]


def pilot_start(plan, k):
    """(noise scale, tau) of layout ``k``'s pilot; None for no plan (an unused slot of a study)."""
    return None if plan is None else plan.run_pilot(k)


def scenario_chunk(plan, k, indices, start):
    """The records of layout ``k`` on the scenarios ``indices`` ([] for no plan)."""
    return [] if plan is None else plan.run_scenarios(k, start, indices)


def add_plan(graph, plan, *, n_layouts, n_scenarios, chunks):
    """Add a plan's pilots and ``chunks`` scenario chunks per layout to ``graph``; ``plan`` is a node (or value).
    Returns the chunks' nodes."""
    nodes = []
    for k in range(n_layouts):
        start = graph.task(pilot_start, plan, k)
        nodes += [graph.task(scenario_chunk, plan, k, run, start, weight=len(run))
                  for run in split(n_scenarios, chunks)]
    return nodes


def plan_records(graph, nodes):
    """The records of a plan's chunk nodes, in the order of :meth:`~.verify.VerificationPlan.tasks`."""
    return [record for node in nodes for record in graph.result(node)]


def run_plans(executor, plans, *, progress=None):
    """The records of every plan (a list per plan), all plans' work in one graph on ``executor``."""
    graph = TaskGraph(executor)
    nodes = [add_plan(graph, graph.constant(p), n_layouts=len(p.layouts), n_scenarios=len(p.scenarios),
                      chunks=chunk_count(executor, len(p.scenarios), len(p.layouts))) for p in plans]
    graph.run(progress)
    return [plan_records(graph, n) for n in nodes]
