"""Placement problems several design test files share."""


def structured_three_span(count=5, criterion="D"):
    """The three-span example's problem on a 0.5 m grid with structured blocks even where dense ones fit."""
    from sensorplan.design import recommend as module
    from sensorplan.design.recommend import CandidateGrid, build_problem
    from sensorplan.io.config import example_case

    keep = module.DENSE_CACHE_BYTES
    module.DENSE_CACHE_BYTES = 0  # structured blocks even where dense ones fit
    try:
        problem = build_problem(example_case("three-span"), count, criterion, grid=CandidateGrid(spacing=0.5))
    finally:
        module.DENSE_CACHE_BYTES = keep
    assert problem.structured
    return problem


def random_e_problem(seed, *, c, p, count, rank=2, twins=False):
    """An E problem: blocks of random rank-``rank`` Jacobians (with ``twins``, a third of the candidates near
    copies of others, so that the relaxed optimum ties many of them, as dense candidate grids do), a random
    positive definite prior."""
    import numpy as np

    from sensorplan.design.criteria.eigenvalue import ECriterion
    from sensorplan.design.problem import DesignProblem

    rng = np.random.default_rng(seed)
    jac = rng.standard_normal((c, rank, p)) * rng.uniform(0.2, 3.0, (c, 1, 1))
    if twins:
        near = rng.integers(0, c, c // 3)
        jac[: c // 3] = jac[near] + 0.01 * rng.standard_normal((c // 3, rank, p))
    blocks = np.einsum("cri,crj->cij", jac, jac)
    a = rng.standard_normal((p, p))
    q0 = a @ a.T / p + 0.1 * np.eye(p)
    return DesignProblem(np.sort(rng.uniform(0.0, 50.0, c)), np.zeros(c, dtype=int), blocks, q0,
                         criterion=ECriterion(p), count=count)
