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

from .._executors import TaskGraph, worker_count

__all__ = ["run_plans", "add_plan", "chunk_size", "pilot_start", "scenario_chunk", "plan_records"]


def chunk_size(executor, n_scenarios, n_layouts=1):
    """Scenarios per task: one without an executor (progress per scenario), else about eight tasks per worker."""
    if executor is None:
        return 1
    return max(1, min(n_scenarios, (n_layouts * n_scenarios) // (8 * worker_count(executor))))


def pilot_start(plan, k):
    """(noise scale, tau) of layout ``k``'s pilot; None for no plan (an unused slot of a study)."""
    return None if plan is None else plan.run_pilot(k)


def scenario_chunk(plan, k, indices, start):
    """The records of layout ``k`` on the scenarios ``indices`` ([] for no plan)."""
    return [] if plan is None else plan.run_scenarios(k, start, indices)


def add_plan(graph, plan, *, n_layouts, n_scenarios, chunk):
    """Add a plan's pilots and scenario chunks to ``graph``; ``plan`` is a node (or value). Returns the chunks' nodes."""
    nodes = []
    for k in range(n_layouts):
        start = graph.task(pilot_start, plan, k)
        nodes += [graph.task(scenario_chunk, plan, k, tuple(range(i, min(i + chunk, n_scenarios))), start,
                             weight=min(chunk, n_scenarios - i)) for i in range(0, n_scenarios, chunk)]
    return nodes


def plan_records(graph, nodes):
    """The records of a plan's chunk nodes, in the order of :meth:`~.verify.VerificationPlan.tasks`."""
    return [record for node in nodes for record in graph.result(node)]


def run_plans(executor, plans, *, progress=None):
    """The records of every plan (a list per plan), all plans' work in one graph on ``executor``."""
    graph = TaskGraph(executor)
    nodes = [add_plan(graph, graph.constant(p), n_layouts=len(p.layouts), n_scenarios=len(p.scenarios),
                      chunk=chunk_size(executor, len(p.scenarios), len(p.layouts))) for p in plans]
    graph.run(progress)
    return [plan_records(graph, n) for n in nodes]
