"""Reproduce the paper's two-span Fisher figure (Fig. FisherInformationTwoSpan).

Two continuous spans of L = 15 m, a full point-load sweep, single rotation
sensors at x/L = 0, 0.1, ..., 1.0 on span 1.  Prints where each curve peaks
and how much information each sensor keeps beyond the interior support,
and writes a figure.

Run: python studies/fisher/paper_two_span.py [--out DIR]
"""

import argparse
from pathlib import Path

import numpy as np

import sensorplan as sp
from sensorplan.model.case import Case
from sensorplan.model.fisher import fisher_blocks
from sensorplan.plotting import plot_informativeness, save_figure

L = 15.0


def main(out):
    bridge = sp.Bridge((L, L))
    case = Case(bridge, sp.Mesh.uniform(bridge, 60), 1e10, sp.Vehicle.point_load(1e5),
                sp.SensorLayout([1.0], noise_std=1e-6),
                sweep=sp.LoadSweep.from_range(0.0, 2 * L, 0.05))
    xs = np.round(np.arange(0.0, 1.01, 0.1), 1) * L
    sensors = sp.SensorLayout(xs, names=tuple(f"x/L={x / L:.1f}" for x in xs), noise_std=1e-6)
    blocks = fisher_blocks(case, sensors=sensors, parameterisation="ei")
    span2 = case.mesh.midpoints > L
    print("Two spans 2 x 15 m, 60 elements, point-load sweep, EI parameterisation")
    print(f"  {'sensor':10s} {'peak x/L':>9s} {'max span 2 / max span 1':>24s}")
    for name, peak, curve in zip(sensors.names, blocks.peaks(), blocks.curves):
        ratio = curve[span2].max() / curve[~span2].max()
        print(f"  {name:10s} {peak / L:9.3f} {ratio:24.3f}")
    right = fisher_blocks(case, sensors=sp.SensorLayout([1.05 * L], names=("x/L=1.05",),
                                                        noise_std=1e-6), parameterisation="ei")
    start = (case.mesh.midpoints > 1.07 * L) & (case.mesh.midpoints < 1.33 * L)
    print(f"  sensor just right of the support (x/L = 1.05) vs best span-1 sensor on "
          f"x/L in (1.07, 1.33): {right.curves[0][start].sum() / blocks.curves[:, start].sum(axis=1).max():.2f}x")
    ax = plot_informativeness(blocks, supports=bridge.support_positions, log=True)
    print("figure:", save_figure(ax, Path(out) / "fisher_two_span.png"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="studies/output")
    main(parser.parse_args().out)
