"""Reproduce the paper's single-span Fisher figure (Fig. FisherInformation).

One simply supported 20 m span, a full sweep of a point load, EI constant.
Sensor at x/L = 1/4 and reference sensors at the supports (x/L = 0 and 1).
Prints where each informativeness curve (diag of I^(i) in the EI
parameterisation, paper eq. fi-diag) peaks and writes a figure.

Run: python studies/fisher/paper_single_span.py [--out DIR]
"""

import argparse
from pathlib import Path

import numpy as np

import sensorplan as sp
from sensorplan.model.case import Case
from sensorplan.model.fisher import fisher_blocks
from sensorplan.plotting import plot_informativeness, save_figure

L = 20.0


def main(out):
    bridge = sp.Bridge((L,))
    case = Case(bridge, sp.Mesh.uniform(bridge, 40), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([0.25 * L], noise_std=1e-6),
                sweep=sp.LoadSweep.from_range(0.0, L, 0.05))
    sensors = sp.SensorLayout([0.0, 0.25 * L, L], names=("x/L=0", "x/L=1/4", "x/L=1"),
                              noise_std=1e-6)
    blocks = fisher_blocks(case, sensors=sensors, parameterisation="ei")
    print("Single span, 40 elements, point load sweep in 0.05 m steps, EI parameterisation")
    for name, peak in zip(sensors.names, blocks.peaks()):
        print(f"  sensor {name:8s}: curve peaks at x/L = {peak / L:.3f}")
    # the paper's rule: maxima near 1/3 for sensors at x/L < 1/3, near 2/3 beyond 2/3
    xs = np.linspace(0.0, 1.0, 21) * L
    scan = fisher_blocks(case, sensors=sp.SensorLayout.candidates(xs, noise_std=1e-6),
                         parameterisation="ei")
    print("  sensor x/L -> peak x/L:",
          ", ".join(f"{x / L:.2f}->{p / L:.3f}" for x, p in zip(xs, scan.peaks())))
    ax = plot_informativeness(blocks, supports=bridge.support_positions)
    print("figure:", save_figure(ax, Path(out) / "fisher_single_span.png"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="studies/output")
    main(parser.parse_args().out)
