"""Structured Fisher blocks (sensorplan.design.blocks) against the dense per-candidate blocks.

Reference: :func:`sensorplan.model.fisher.fisher_blocks`, which forms each
sensor's kernel by the element products of its own actual moment diagram
(no shared fixed matrices, no cumulative sums): the structured sums, inner
products and congruences must agree with the dense ones to round-off.
"""

import numpy as np
import pytest

from sensorplan.design.blocks import structured_fisher
from sensorplan.io.config import case_from_toml
from sensorplan.model.fisher import fisher_blocks
from sensorplan.model.sensors import SensorLayout

CASE = """
[case]
name = "blocks"

[bridge]
spans = [20.0, 25.0, 15.0]
ei = 2.0e11
elements = 37
{springs}

[vehicle]
axle_offsets = [0.0, 3.5, 4.9]
axle_loads = [60.0e3, 50.0e3, 50.0e3]

[sensors]
names = ["T1", "D1"]
positions = [15.0, 50.0]
kinds = ["rotation", "deflection"]
noise_std = [5.0e-6, 1.0e-4]

[loads]
start = -2.0
stop = 66.0
step = 0.5

{noise}
"""

SPRINGS = "rotational_springs = [5.0e8, 0.0, 0.0, 0.0]\nvertical_springs = [inf, 2.0e8, inf, inf]"
AR1 = "[noise]\ncorrelation_length = 3.0"
TIME = "[noise]\ncorrelated_std = [2.0e-6, 3.0e-5]\ncorrelation_time_s = 0.5\nrandom_walk = [1.0e-7, 1.0e-6]\nspeed = 10.0"

VARIANTS = {"plain": ("", ""), "springs": (SPRINGS, ""), "ar1": ("", AR1), "time": ("", TIME),
            "springs+time": (SPRINGS, TIME)}


def _setup(name, rng):
    springs, noise = VARIANTS[name]
    case = case_from_toml(CASE.format(springs=springs, noise=noise), name="blocks")
    edges = case.mesh.edges
    # random positions, element edges, supports and both ends; both kinds
    x = np.concatenate([rng.uniform(0.0, 60.0, 24), edges[[0, 5, 11, -1]], [20.0, 45.0, 33.3]])
    kinds = tuple("rotation" if i % 2 else "deflection" for i in range(x.size))
    std = tuple(5e-6 if k == "rotation" else 1e-4 for k in kinds)
    sensors = SensorLayout(x, kinds, tuple(f"s{i}" for i in range(x.size)), std)
    return case, sensors, case.noise_for(sensors), bool(springs)


@pytest.mark.parametrize("name", list(VARIANTS))
def test_structured_blocks_equal_dense(name):
    rng = np.random.default_rng(3)
    case, sensors, noise, springs = _setup(name, rng)
    dense = fisher_blocks(case, sensors=sensors, noise=noise, parameterisation="log_ei", springs=springs,
                          n_crossings=3).blocks
    blocks = structured_fisher(case, sensors, noise, n_crossings=3, springs=springs)
    scale = np.abs(dense).max()
    assert blocks.shape == dense.shape
    assert np.abs(blocks[np.arange(sensors.n_sensors)] - dense).max() <= 1e-10 * scale
    w = rng.uniform(0.0, 1.0, sensors.n_sensors)
    assert np.abs(blocks.weighted(w) - np.tensordot(w, dense, 1)).max() <= 1e-10 * scale * w.sum()
    g = rng.standard_normal(dense.shape[1:])
    ref = np.einsum("cij,ij->c", dense, 0.5 * (g + g.T))
    assert np.abs(blocks.dot(g) - ref).max() <= 1e-10 * np.abs(ref).max()
    v = np.linalg.qr(rng.standard_normal((dense.shape[1], 4)))[0]
    ref = np.einsum("ip,cij,jq->cpq", v, dense, v)
    assert np.abs(blocks.congruence(v) - ref).max() <= 1e-10 * np.abs(ref).max()
    pick = [7, 2, 30]
    sub = blocks.subset(pick)
    assert np.abs(sub[np.arange(3)] - dense[pick]).max() <= 1e-10 * scale
    assert np.abs(sub.congruence(v) - ref[pick]).max() <= 1e-10 * np.abs(ref).max()
    assert np.abs(blocks[4] - dense[4]).max() <= 1e-10 * scale


@pytest.mark.parametrize("name", ["plain", "springs"])
def test_families_keep_only_the_fixed_matrices_they_use(name):
    # tiltmeters only: the load moment's integral against s never enters (their atoms are steps), and on pinned
    # supports some redundant's diagram may carry no load moment; what is kept still gives the dense blocks
    rng = np.random.default_rng(5)
    case, _, _, springs = _setup(name, rng)
    x = np.sort(rng.uniform(0.0, 60.0, 40))
    sensors = SensorLayout(x, ("rotation",) * x.size, tuple(f"t{i}" for i in range(x.size)), (5e-6,) * x.size)
    noise = case.noise_for(sensors)
    dense = fisher_blocks(case, sensors=sensors, noise=noise, parameterisation="log_ei", springs=springs).blocks
    blocks = structured_fisher(case, sensors, noise, springs=springs)
    (family,) = blocks.families
    n_a = family.products.shape[0]
    assert np.all(np.any(family.coef != 0.0, axis=0))
    assert all(np.any(family.products[a, :, a, :] != 0.0) for a in range(n_a))
    assert n_a - family.n_free == 1  # the integral against 1 only
    assert np.abs(blocks[np.arange(x.size)] - dense).max() <= 1e-10 * np.abs(dense).max()
    v = np.linalg.qr(rng.standard_normal((dense.shape[1], 6)))[0]
    ref = np.einsum("ip,cij,jq->cpq", v, dense, v)
    assert np.abs(blocks.congruence(v) - ref).max() <= 1e-10 * np.abs(ref).max()


def test_congruences_from_the_readings_equal_the_dense_ones():
    # eight spans with end springs: nine redundant diagrams and few load positions, so that the free part of the
    # congruences is formed from the whitened readings Psi_a V (not from the pair products); reference: the dense
    # blocks of fisher_blocks
    case = case_from_toml(CASE.replace("spans = [20.0, 25.0, 15.0]", "spans = [15.0, 20.0, 20.0, 20.0, 20.0, 20.0, 20.0, 15.0]")
                          .replace("elements = 37", "elements = 120").replace("stop = 66.0", "stop = 156.0")
                          .replace("step = 0.5", "step = 1.0")
                          .format(springs="rotational_springs = [4.0e8, 0, 0, 0, 0, 0, 0, 0, 4.0e8]", noise=""),
                          name="eight")
    rng = np.random.default_rng(11)
    x = rng.uniform(0.0, 150.0, 30)
    sensors = SensorLayout(x, ("rotation",) * x.size, tuple(f"t{i}" for i in range(x.size)), (5e-6,) * x.size)
    noise = case.noise_for(sensors)
    dense = fisher_blocks(case, sensors=sensors, noise=noise, parameterisation="log_ei", springs=True).blocks
    blocks = structured_fisher(case, sensors, noise, springs=True)
    (family,) = blocks.families
    f, (_, n_loads, p) = family.n_free, family.readings.shape
    for k in (3, 8):
        assert f * (f + 1) // 2 * p * p > 1.2 * f * n_loads * (p + f * k)  # the readings' route is the cheaper
        v = np.linalg.qr(rng.standard_normal((dense.shape[1], k)))[0]
        ref = np.einsum("ip,cij,jq->cpq", v, dense, v)
        assert np.abs(blocks.congruence(v) - ref).max() <= 1e-10 * np.abs(ref).max()


@pytest.mark.parametrize("criterion", ["D", "A", "E"])
def test_search_on_structured_blocks_equals_the_search_on_dense_ones(monkeypatch, criterion):
    # reference: the same problem with its blocks stored densely (one block at a time, no batches, no cache)
    from dataclasses import replace

    from sensorplan.design import recommend as module
    from sensorplan.design.recommend import CandidateGrid, build_problem

    monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)  # structured blocks even where dense ones fit
    from sensorplan.design.selection import exchange, greedy
    from sensorplan.io.config import example_case

    problem = build_problem(example_case("three-span"), 4, criterion, grid=CandidateGrid(spacing=1.0))
    assert problem.structured
    dense = replace(problem, blocks=problem.blocks[np.arange(problem.n_candidates)])
    assert not dense.structured
    g_structured, u_structured = greedy(problem)
    g_dense, u_dense = greedy(dense)
    assert g_structured == g_dense and u_structured == pytest.approx(u_dense, rel=1e-12)
    start = list(range(0, problem.n_candidates, problem.n_candidates // 4))[:4]
    e_structured, v_structured = exchange(problem, start)
    e_dense, v_dense = exchange(dense, start)
    assert sorted(e_structured) == sorted(e_dense) and v_structured == pytest.approx(v_dense, rel=1e-12)


@pytest.mark.parametrize("example, criterion, kind", [("three-span", "D", "rotation"),
                                                      ("openlab-like", "A", ("rotation", "deflection"))])
def test_recommend_on_structured_blocks_equals_recommend_on_dense_ones(monkeypatch, example, criterion, kind):
    # recommend holds dense blocks while they fit DENSE_CACHE_BYTES, structured ones beyond: forced here
    from sensorplan.design import recommend as module
    from sensorplan.io.config import example_case

    case = example_case(example)
    noise = {"rotation": 5e-6, "deflection": 2e-5}
    options = dict(kind=kind, noise_std=noise if isinstance(kind, tuple) else None, curve_max=4)
    dense = module.recommend(case, 4, criterion, **options)
    monkeypatch.setattr(module, "DENSE_CACHE_BYTES", 0)
    structured = module.recommend(case, 4, criterion, **options)
    assert structured.layout_m == dense.layout_m and structured.layout_kind == dense.layout_kind
    assert structured.value == pytest.approx(dense.value, rel=1e-9)
    assert structured.bound == pytest.approx(dense.bound, rel=1e-6)
    assert [p.value for p in structured.curve] == pytest.approx([p.value for p in dense.curve], rel=1e-9)
