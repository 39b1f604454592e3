"""Reproduce the paper's noise-level study (Figs. rot_fit and matrix).

A simply supported 20 m span (EI = 1e10 N m^2) with a 35 % loss of EI over
x = 12.5-14.5 m, two tiltmeters at x = 4 m and 16 m, one crossing of a
100 kN point load in 0.25 m steps.  The data are simulated on a 40-element
mesh whose damage edges do not coincide with the 10-element inversion mesh
(no inverse crime).  For tilt noise sigma = 0.02, 0.01, 0.005, 0.001 mm/m
the same standard-normal draw is scaled (common random numbers) and EI is
identified on 10 elements (log-EI GMRF prior, noise scale and tau
integrated out; the tau printed is the mode of its hyper-posterior).  Prints, per sigma, the mean 95 % band width relative to the
nominal EI, the relative RMSE of the posterior mean against the element
truth and the EI of the damaged element against its truth, both for the
figure's noise draw and averaged over further draws, then whether the bands
contract and the damage sharpens as sigma falls.  Writes a 2 x 2 figure of
the posteriors and a figure of the rotation fit at sigma = 0.02 mm/m.

Run: python studies/inversion/paper_noise_levels.py [--out DIR]
"""

import os
import sys

if "numpy" not in sys.modules:  # run as a script: one BLAS thread (small matrices; threads only slow them)
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

import sensorplan as sp  # noqa: E402
from sensorplan.model.case import Case  # noqa: E402
from sensorplan.inference.inversion import invert  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402
from sensorplan.plotting import new_figure, plot_ei_posterior, plot_fit, save_figure  # noqa: E402

L = 20.0
EI0 = 1e10
DAMAGE = (12.5, 14.5)          # m, damaged zone (edges off the 2 m inversion grid)
LOSS = 0.35                    # relative EI loss in the damaged zone
SENSORS = (4.0, 16.0)          # m, x/L = 0.2 and 0.8
SIGMAS_MM_PER_M = (0.02, 0.01, 0.005, 0.001)
N_ELEMENTS = 10
N_FINE = 40                    # truth mesh, 4x finer
STEP = 0.25                    # m, load positions
SEED = 0                       # noise draw shown in the figure
N_DRAWS = 10                   # noise draws for the averaged figures of merit


def make_case(n_elements, sigma_rad):
    bridge = sp.Bridge((L,))
    return Case(bridge, sp.Mesh.uniform(bridge, n_elements), EI0, sp.Vehicle.point_load(1e5),
                sp.SensorLayout(list(SENSORS), names=("T1", "T2"), noise_std=sigma_rad),
                sweep=sp.LoadSweep.from_range(0.0, L, STEP))


def truth_fine(mesh):
    x = mesh.midpoints
    return np.where((x > DAMAGE[0]) & (x < DAMAGE[1]), (1.0 - LOSS) * EI0, EI0)


def metrics(res, truth, damaged):
    ci = res.credible_interval(0.95)
    width = (ci[:, 1] - ci[:, 0]) / res.ei_nominal
    return {
        "width": float(np.mean(width)),
        "widths": width,
        "rmse": float(np.sqrt(np.mean(((res.ei_mean - truth) / truth) ** 2))),
        "ei_dmg": float(res.ei_mean[damaged]),
        "ci_dmg": ci[damaged],
        "err_dmg": float(abs(res.ei_mean[damaged] - truth[damaged]) / truth[damaged]),
        "width_dmg": float(width[damaged]),
        "coverage": float(np.mean((truth >= ci[:, 0]) & (truth <= ci[:, 1]))),
        "cover_dmg": float(ci[damaged, 0] <= truth[damaged] <= ci[damaged, 1]),
    }


def main(out):
    coarse = make_case(N_ELEMENTS, 1e-6)
    fine_mesh = sp.Mesh.uniform(coarse.bridge, N_FINE)
    ei_fine = truth_fine(fine_mesh)
    k = N_FINE // N_ELEMENTS
    # element truth: the element-average compliance (paper eq. v_avg)
    truth = 1.0 / np.mean((1.0 / ei_fine).reshape(N_ELEMENTS, k), axis=1)
    damaged = int(np.argmin(truth))
    ends = np.array([0, N_ELEMENTS - 1])
    interior = np.arange(2, N_ELEMENTS - 2)
    print(f"Simply supported {L:g} m span, EI = {EI0:.3g} N m^2, {LOSS:.0%} EI loss on "
          f"x = {DAMAGE[0]:g}-{DAMAGE[1]:g} m; tiltmeters at x = {SENSORS[0]:g}, {SENSORS[1]:g} m")
    print(f"  point load 100 kN, {coarse.sweep.n_loads} positions ({STEP:g} m steps), one crossing; "
          f"truth on {N_FINE} elements, inversion on {N_ELEMENTS} elements "
          "(log-EI GMRF order 1, noise scale and tau integrated out)")
    print(f"  damaged element {damaged}: x = {coarse.mesh.edges[damaged]:g}-"
          f"{coarse.mesh.edges[damaged + 1]:g} m, element truth (compliance average) "
          f"EI = {truth[damaged]:.4g}")
    shown, averaged = [], []
    results = []
    for s_mm in SIGMAS_MM_PER_M:
        sigma = s_mm * 1e-3  # mm/m -> rad
        case = make_case(N_ELEMENTS, sigma)
        fine = case.with_mesh(fine_mesh)
        draws = []
        for seed in range(SEED, SEED + N_DRAWS):
            data = simulate_crossings(fine, 1, noise=True, rng=seed, ei=ei_fine)
            res = invert(case, data, detect=False)  # the paper's GMRF posterior
            if not res.converged:
                print(f"  NOTE: sigma = {s_mm} mm/m, draw {seed}: inversion did not converge")
            draws.append(metrics(res, truth, damaged))
            if seed == SEED:
                results.append((s_mm, res))
        shown.append(draws[0])
        averaged.append({key: float(np.mean([d[key] for d in draws]))
                         for key in ("width", "rmse", "err_dmg", "width_dmg", "ei_dmg", "coverage",
                                     "cover_dmg")})
        averaged[-1]["widths"] = np.mean([d["widths"] for d in draws], axis=0)

    print(f"\n  figure's noise draw (seed {SEED}):")
    print(f"  {'sigma [mm/m]':>12s} {'tau':>8s} {'noise scale':>11s} {'mean 95% width/EI0':>18s} "
          f"{'RMSE/EI':>8s} {'EI damaged (95 % band)':>34s} {'truth':>9s}")
    for (s_mm, res), m in zip(results, shown):
        print(f"  {s_mm:12.3f} {res.tau:8.3g} {res.noise_scale:11.3f} {m['width']:18.3f} "
              f"{m['rmse']:8.3f} {m['ei_dmg']:10.4g} ({m['ci_dmg'][0]:.3g} to {m['ci_dmg'][1]:.3g}) "
              f"{truth[damaged]:9.4g}")
    print(f"\n  averaged over {N_DRAWS} noise draws:")
    print(f"  {'sigma [mm/m]':>12s} {'mean 95% width/EI0':>18s} {'RMSE/EI':>8s} {'EI damaged':>10s} "
          f"{'|error| damaged':>15s} {'width damaged':>13s} {'width ends/interior':>19s} "
          f"{'95% coverage':>12s} {'damaged covered (fraction)':>26s}")
    for s_mm, m in zip(SIGMAS_MM_PER_M, averaged):
        ratio = m["widths"][ends].mean() / m["widths"][interior].mean()
        print(f"  {s_mm:12.3f} {m['width']:18.3f} {m['rmse']:8.3f} {m['ei_dmg']:10.4g} "
              f"{m['err_dmg']:15.3f} {m['width_dmg']:13.3f} {ratio:19.2f} {m['coverage']:12.2f} "
              f"{m['cover_dmg']:26.1f}")
    print("\n  mean relative 95 % width per element (averaged over draws):")
    print("  " + " " * 12 + " ".join(f"{x:6.1f}" for x in coarse.mesh.midpoints) + "   (element midpoint x [m])")
    for s_mm, m in zip(SIGMAS_MM_PER_M, averaged):
        print(f"  {s_mm:8.3f} mm/m" + " ".join(f"{w:6.2f}" for w in m["widths"]))

    def decreasing(values):
        return bool(np.all(np.diff(values) < 0.0))

    avg_width = [m["width"] for m in averaged]
    contract = decreasing(avg_width)
    print(f"\n  bands contract: {'yes' if contract else 'no'} (mean 95 % width/EI0 averaged over "
          f"{N_DRAWS} draws: " + " -> ".join(f"{w:.3f}" for w in avg_width) + ")")
    print(f"  in the figure's draw alone the width falls monotonically: "
          f"{'yes' if decreasing([m['width'] for m in shown]) else 'no'} ("
          + " -> ".join(f"{m['width']:.3f}" for m in shown) + ")")
    err = [m["err_dmg"] for m in averaged]
    wd = [m["width_dmg"] for m in averaged]
    sharp = decreasing(err) and decreasing(wd)
    print(f"  damage sharpens: {'yes' if sharp else 'no'} (damaged element, averaged: |error| "
          + " -> ".join(f"{e:.3f}" for e in err) + "; 95 % width " + " -> ".join(f"{w:.3f}" for w in wd)
          + ")")
    low = averaged[-1]
    print(f"  at sigma = {SIGMAS_MM_PER_M[-1]} mm/m the end elements keep "
          f"{low['widths'][ends].mean() / low['widths'][interior].mean():.1f}x the interior band width "
          f"(at {SIGMAS_MM_PER_M[0]} mm/m: "
          f"{averaged[0]['widths'][ends].mean() / averaged[0]['widths'][interior].mean():.1f}x)")

    fig, axes = new_figure((11, 7), 2, 2, sharey=True)
    for ax, (s_mm, res) in zip(axes.ravel(), results):
        plot_ei_posterior(res, ax=ax, supports=coarse.bridge.support_positions,
                          truth=(fine_mesh.edges, ei_fine))
        ax.set_title(f"sigma = {s_mm:g} mm/m ({N_ELEMENTS} elements)")
        ax.set_ylim(0.4 * EI0, 1.6 * EI0)  # the truth stairs are drawn from a zero baseline
    print("figure:", save_figure(fig, Path(out) / "inversion_noise_levels.png"))
    res = results[0][1]
    fig, axes = new_figure((11, 3.6), 1, 2)
    for i, ax in enumerate(axes):
        plot_fit(res, i, ax=ax)
        ax.set_title(f"{res.sensor_names[i]} at x = {SENSORS[i]:g} m, sigma = {results[0][0]:g} mm/m")
    print("figure:", save_figure(fig, Path(out) / "inversion_noise_levels_fit.png"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="studies/output")
    main(parser.parse_args().out)
