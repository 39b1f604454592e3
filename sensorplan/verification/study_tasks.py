"""The work of a design study as one task graph: designs, then every distinct layout's verification.

A design study's work is: one recommendation per (case, count, criterion),
then for each case the verification of its distinct layouts (the
recommended ones and the chosen feasible baselines), each a pilot and its
scenarios in chunks.  Which layouts a case has is known only once its
designs are done, so the graph has a *slot* per layout a case can have at
most (each of its designs recommends one layout and offers each chosen
baseline): the slot's task picks the slot's layout among the designs'
distinct layouts, in order of first appearance, or nothing.  So every task
is known up front and the whole study is submitted at once
(:class:`sensorplan._executors.TaskGraph`); a slot left empty costs three
trivial tasks.  Each slot's one-layout plan has the case's scenarios and
seeds, so its records equal those of the case's plan for that layout.

Owns: the study's tasks and slots.  May import: design, the verification and the foundations.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING

from .._executors import TaskGraph
from .dispatch import add_plan, chunk_count, plan_records
from .scenarios import make_scenarios
from .verify import plan_verification

if TYPE_CHECKING:
    from ..model.case import Case

__all__ = ["DesignJob", "Candidate", "recommend_job", "distinct_layouts", "slot_plan", "run_study", "keep_row"]


@dataclass(frozen=True)
class DesignJob:
    """One (case, count, criterion) to recommend, with the design options every job shares."""

    case: "Case"
    count: int
    criterion: str
    spacing: float
    n_crossings: int
    seed: int


@dataclass(frozen=True)
class Candidate:
    """A layout a design offers for verification: the recommended one or a feasible baseline."""

    name: str
    layout_m: tuple
    value: float
    efficiency: float


def recommend_job(job):
    """The recommended layout and the feasible baselines of one job; run on a worker."""
    from ..design.recommend import CandidateGrid, recommend

    design = recommend(job.case, job.count, job.criterion, grid=CandidateGrid(spacing=job.spacing),
                       kind=job.case.default_kind, n_crossings=job.n_crossings, rng=job.seed, curve_max=0)
    rows = [Candidate("recommended", design.layout_m, design.value, design.efficiency)]
    rows += [Candidate(b.name, b.layout_m, b.value, min(1.0, b.relative * design.efficiency))
             for b in design.baselines if b.feasible]
    return rows


def keep_row(name, baselines):
    """Whether a design's row ``name`` is verified under the study's ``baselines`` option."""
    if name == "recommended":
        return True
    if isinstance(baselines, bool):
        return baselines
    return name in baselines


def distinct_layouts(designs, baselines):
    """The distinct layouts the rows of ``designs`` (one case's) verify, in order of first appearance."""
    return list(dict.fromkeys(row.layout_m for rows in designs for row in rows if keep_row(row.name, baselines)))


def slot_plan(case, slot, designs, baselines, options):
    """The one-layout VerificationPlan of ``case``'s layout number ``slot`` (None when it has fewer)."""
    layouts = distinct_layouts(designs, baselines)
    if slot >= len(layouts):
        return None
    return plan_verification(case, [layouts[slot]], kind=case.default_kind, **options)


def _slots(n_designs, baselines):
    """The most distinct layouts ``n_designs`` designs can offer under ``baselines``."""
    from ..design.baselines import BASELINES

    per_design = 1 + (len(BASELINES) if baselines is True else 0 if baselines is False else len(set(baselines)))
    return n_designs * per_design


def run_study(executor, cases, jobs, *, baselines, options, progress=None):
    """Every design and every case's verification records, all in one graph on ``executor``.

    Returns (designs: the rows of each job, records: per case, per slot, the records of its layout).
    ``progress(done, total)`` counts a design as 1 and a scenario as 1.
    """
    graph = TaskGraph(executor)
    design_nodes = [graph.task(recommend_job, job, weight=1) for job in jobs]
    per_case = []
    for case in cases:
        mine = [node for job, node in zip(jobs, design_nodes) if job.case is case]
        n_scen = len(make_scenarios(case, options["n_locations"], severity=options["severity"],
                                    length=options["length"], n_controls=options["n_controls"]))
        n_slots = _slots(len(mine), baselines)
        chunks = chunk_count(executor, n_scen, n_slots)
        case_node = graph.constant(case)
        per_case.append([add_plan(graph, graph.task(slot_plan, case_node, s, mine, baselines, options),
                                  n_layouts=1, n_scenarios=n_scen, chunks=chunks) for s in range(n_slots)])
    graph.run(progress)
    designs = [graph.result(node) for node in design_nodes]
    return designs, [[plan_records(graph, slot) for slot in slots] for slots in per_case]
