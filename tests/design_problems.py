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
