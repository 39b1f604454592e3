"""The detect design at scale: exact zone signatures without a solve per zone, and the resource estimate.

* :class:`~sensorplan.model.forward.ZoneChanges` (the redundants' change
  by a Woodbury update of the force method, all integrals over the zone's
  elements) against the difference of two full forward solves
  (``influence_lines`` at the damaged and the nominal EI on the zone's own
  mesh): an independent computation of the same exact change;
* the whitened signatures of :class:`SignatureModel` streamed one centre at
  a time (``damage_each``) against ``damage`` for all centres at once;
* the detect criterion's resource estimate (the CLI's up-front check):
  grows with the candidates, is refused with a one-line error beyond the
  machine, and its suggested spacing passes the same check.
"""

import numpy as np
import pytest

from sensorplan.cli import main
from sensorplan.design.detect_problem import detection_resources
from sensorplan.design.resources import RESOURCES
from sensorplan.detection.signatures import SignatureModel, zone_mesh_edges
from sensorplan.io.config import example_case
from sensorplan.model.forward import ZoneChanges, influence_lines
from sensorplan.model.sensors import SensorLayout
from sensorplan.model.structure import Mesh


def _mid_inside(edges, low, high):
    mid = 0.5 * (edges[1:] + edges[:-1])
    return (mid > low) & (mid < high)


@pytest.mark.parametrize("example", ["three-span", "openlab-like", "simply-supported"])
def test_zone_changes_equal_two_full_forward_solves(example):
    case = example_case(example)
    length = case.bridge.length
    sensors = SensorLayout(np.linspace(0.3, length - 0.3, 5), ["rotation", "deflection"] * 2 + ["rotation"])
    positions = case.sweep.positions
    centres = np.array([1.0, 0.37 * length, 0.5 * length + 0.13, length - 1.0])  # ends, supports' sides
    lows, highs = centres - 1.0, centres + 1.0
    edges = zone_mesh_edges(case.mesh, case.bridge, np.concatenate([lows, highs]))
    mesh = Mesh(edges)
    changes = ZoneChanges(case.bridge, mesh, case.ei_at(mesh.midpoints), sensors, case.vehicle, positions)
    for low, high, severity in zip(lows, highs, (0.25, 0.5, 0.1, 0.4)):
        # reference: the zone's own mesh, damaged and nominal EI, two independent full solves
        own = Mesh(zone_mesh_edges(case.mesh, case.bridge, [low, high]))
        nominal = case.ei_at(own.midpoints)
        damaged = nominal * np.where(_mid_inside(own.edges, low, high), 1.0 - severity, 1.0)
        ref = (influence_lines(case.bridge, own, damaged, sensors, case.vehicle, positions).predictions
               - influence_lines(case.bridge, own, nominal, sensors, case.vehicle, positions).predictions)
        inside = np.nonzero(_mid_inside(edges, low, high))[0]
        got = changes.change(inside[0], inside[-1] + 1, 1.0 - severity)
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9 * np.abs(ref).max())


def test_streamed_signatures_equal_the_batch():
    case = example_case("three-span")
    sensors = SensorLayout([3.0, 11.0, 17.5], ["rotation"] * 3)
    model = SignatureModel(case, sensors, case.noise_for(sensors), "smooth", 2.0)
    centres = np.array([1.0, 6.5, 14.0])
    batch = model.damage(centres, 0.3)
    for c, signal in enumerate(model.damage_each(centres, 0.3)):
        np.testing.assert_allclose(signal, batch[c], rtol=1e-12, atol=1e-12 * np.abs(batch).max())


def test_detect_resource_estimate_grows_with_the_candidates():
    case = example_case("three-span")
    small, large = detection_resources(case, 100, 4), detection_resources(case, 10_000, 4)
    assert large.memory_bytes > small.memory_bytes and large.cpu_seconds > small.cpu_seconds
    # the packed blocks alone are a floor: C x 8 (n_centres (1 + n) + n^2) bytes
    n_centres, n = small.n_params, 3 * case.bridge.n_spans + len(case.bridge.spring_names)
    assert large.memory_bytes >= 8 * 10_000 * (n_centres * (1 + n) + n * n)
    assert detection_resources(case, 100, 4, step=0.25).n_params > n_centres
    assert RESOURCES.memory_fraction < 1.0


def test_cli_refuses_a_detect_grid_beyond_the_estimate_and_accepts_its_suggestion(capsys, tmp_path):
    argv = ["recommend", "--example", "openlab-like", "--count", "2", "--criterion", "detect", "--spacing",
            "1e-7", "--out", str(tmp_path / "a")]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "GiB" in err and "--spacing >=" in err
    suggested = float(err.rsplit("--spacing >= ", 1)[1].rstrip("."))
    from sensorplan.cli._common import check_design_resources

    class Args:
        spacing, kind, springs, count, criterion = suggested, None, False, 2, "detect"
        length, step, nuisance, target_power = None, None, None, None

    check_design_resources(example_case("openlab-like"), Args)  # no refusal at the suggested spacing
