"""Reproduce the paper's openLAB field application on synthetic data (Figs. EI distribution 6 and 32).

The openLAB-like two-span frame (example "openlab-like": spans 2 x 15 m,
rotational springs at the outer supports, a two-axle 4.9 t vehicle, tiltmeters
PE1 and PE2 at x = 11 m and 19 m, 4 m either side of the middle support,
noise 5 urad).  Ten crossings are simulated on a 120-element mesh with span 1
softer as in the example (EI = 7.5e9 / 1.0e10 N m^2) and slightly changed
springs (2.4e9 and 0.8e9 N m/rad instead of 2e9 and 1e9), using only the
constant-speed segment of the track (reference axle at 5-30 m) as in the
paper.  EI is then identified with the end springs estimated jointly, on 6
elements and on 1 m elements (30), from a prior whose nominal EI is the SAME
on both spans (1e10), so any difference between the spans comes from the
data.  Prints the EI per element with 95 % bands, the springs, the posterior
probability that span 1 is softer than span 2, and where the relative band
width is largest, set against the root-mean-square bending moment over the
crossing (small moment = little leverage on EI).  Writes figures of both
posteriors and of the data-model fit.

Run: python studies/inversion/openlab_frame.py [--out DIR]
"""

import os
import sys

if "numpy" not in sys.modules:  # run as a script: one BLAS thread (small matrices; threads only slow them)
    for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

import sensorplan as sp  # noqa: E402
from sensorplan.io.config import example_case  # noqa: E402
from sensorplan.inference.inversion import invert  # noqa: E402
from sensorplan.model.simulate import simulate_crossings  # noqa: E402
from sensorplan.plotting import new_figure, plot_ei_posterior, plot_fit, save_figure  # noqa: E402

N_FINE = 120
MESHES = (6, 30)
N_CROSSINGS = 10
TRUE_SPRINGS = (2.4e9, 0.8e9)   # N m/rad at x = 0 and x = 30 m (nominal 2e9, 1e9)
SEGMENT = (5.0, 30.0)           # m, constant-speed part of the track
NOMINAL_EI = 1e10               # prior centre, the same on both spans
SEED = 2025


def span_contrast(res, span1):
    """Posterior of mean log EI(span 1) - mean log EI(span 2): mean, sd, P(< 0)."""
    n = res.n_elements
    c = np.where(span1, 1.0 / span1.sum(), -1.0 / (~span1).sum())
    mean = float(c @ res.theta[:n])
    sd = float(np.sqrt(c @ res.covariance[:n, :n] @ c))
    return mean, sd, float(stats.norm.cdf(-mean / sd))


def main(out):
    example = example_case("openlab-like")
    bridge = example.bridge
    supports = bridge.support_positions
    fine = example.with_mesh(sp.Mesh.uniform(bridge, N_FINE))
    true_bridge = bridge.with_spring_stiffness(list(TRUE_SPRINGS))
    sweep = example.sweep.positions
    positions = sweep[(sweep >= SEGMENT[0]) & (sweep <= SEGMENT[1])]
    data = simulate_crossings(fine, N_CROSSINGS, noise=True, rng=SEED, bridge=true_bridge,
                              positions=positions)
    print("openLAB-like frame: spans 2 x 15 m, rotational springs at x = 0 and 30 m, "
          "two-axle 2 x 24 kN vehicle, PE1 at 11 m, PE2 at 19 m, noise 5 urad")
    print(f"  truth ({N_FINE} elements): EI = {fine.ei[0]:.3g} (span 1) / {fine.ei[-1]:.3g} (span 2); "
          f"springs {TRUE_SPRINGS[0]:.3g}, {TRUE_SPRINGS[1]:.3g} N m/rad; {N_CROSSINGS} crossings, "
          f"reference axle {positions[0]:g}-{positions[-1]:g} m ({positions.size} positions)")
    print(f"  prior: nominal EI {NOMINAL_EI:.3g} on both spans, springs nominal "
          f"{bridge.rotational_springs[0]:.3g}, {bridge.rotational_springs[2]:.3g} N m/rad; "
          "GMRF order 1, noise scale and tau integrated out (hyper-posterior mode of tau shown)")
    results = {}
    for n in MESHES:
        case = replace(example, mesh=sp.Mesh.uniform(bridge, n), ei=NOMINAL_EI)
        res = invert(case, data, detect=False)  # the paper's GMRF posterior
        results[n] = res
        mesh = case.mesh
        true_el = 1.0 / np.array([np.mean(1.0 / fine.ei[(fine.mesh.midpoints > a) & (fine.mesh.midpoints < b)])
                                  for a, b in zip(mesh.edges[:-1], mesh.edges[1:])])
        ci = res.credible_interval(0.95)
        rel = (ci[:, 1] - ci[:, 0]) / res.ei_mean
        # leverage: rms over the crossing of the true bending moment at the element midpoints
        moments = sp.bending_moments(true_bridge, fine.mesh, fine.ei, example.vehicle, positions,
                                     mesh.midpoints)
        m_rms = np.sqrt(np.mean(moments**2, axis=0))
        print(f"\n{n} elements: converged {res.converged} after {res.n_iter} iterations, noise scale "
              f"{res.noise_scale:.3f}, tau {res.tau:.3g}")
        print(f"  {'x [m]':>11s} {'EI mean':>10s} {'95 % band':>21s} {'truth':>9s} {'rel. width':>10s} "
              f"{'M_rms/max':>9s}")
        for j in range(n):
            print(f"  {mesh.edges[j]:5.1f}-{mesh.edges[j + 1]:<5.1f} {res.ei_mean[j]:10.4g} "
                  f"{ci[j, 0]:10.4g}-{ci[j, 1]:<10.4g} {true_el[j]:9.4g} {rel[j]:10.3f} "
                  f"{m_rms[j] / m_rms.max():9.3f}")
        covered = np.mean((true_el >= ci[:, 0]) & (true_el <= ci[:, 1]))
        print(f"  truth inside the 95 % band in {covered:.0%} of the elements")
        for name, s in res.springs().items():
            true_k = TRUE_SPRINGS[0] if name.endswith("_0") else TRUE_SPRINGS[1]
            print(f"  spring {name}: {s['map']:.3g} N m/rad (95 % {s['low']:.3g} to {s['high']:.3g}; "
                  f"nominal {s['nominal']:.3g}, truth {true_k:.3g})")
        span1 = mesh.midpoints < supports[1]
        avg1 = float(np.exp(np.mean(np.log(res.ei_mean[span1]))))
        avg2 = float(np.exp(np.mean(np.log(res.ei_mean[~span1]))))
        mean, sd, prob = span_contrast(res, span1)
        verdict = "softer" if avg1 < avg2 and prob > 0.95 else "NOT clearly softer"
        print(f"  span 1 identified {verdict} than span 2: geometric-mean EI {avg1:.3g} vs {avg2:.3g} "
              f"(ratio {avg1 / avg2:.3f}, truth 0.750); P(span 1 softer) = {prob:.4f}")
        order = np.argsort(rel)[::-1]
        dist = np.min(np.abs(mesh.midpoints[:, None] - supports[None, :]), axis=1)
        print("  widest relative 95 % bands: " + "; ".join(
            f"x = {mesh.edges[j]:g}-{mesh.edges[j + 1]:g} m (width {rel[j]:.2f}, {dist[j]:.1f} m from "
            f"the support at {supports[np.argmin(np.abs(supports - mesh.midpoints[j]))]:g} m, "
            f"M_rms {m_rms[j] / m_rms.max():.2f} of max)" for j in order[:3]))
        rho = stats.spearmanr(rel, m_rms).statistic
        print(f"  rank correlation of band width with M_rms: {rho:+.2f} "
              f"({'wider where the moment is small' if rho < -0.5 else 'weak link to the moment'})")
        end_max = max(rel[0], rel[-1])
        print(f"  widest band next to an outer support: {'yes' if order[0] in (0, n - 1) else 'no'}; "
              f"end elements: {rel[0]:.2f} at x = 0 m, {rel[-1]:.2f} at x = 30 m (right end "
              f"{'widest' if rel[-1] >= rel[0] else 'not the widest'}; interior median {np.median(rel):.2f}"
              f", max end / interior median {end_max / np.median(rel):.1f}x)")
        corr = res.covariance / np.outer(res.std, res.std)
        print("  posterior correlation of the spring log-stiffness with log EI of the adjacent end element: "
              + ", ".join(f"{name} {corr[n + i, 0 if name.endswith('_0') else n - 1]:+.2f}"
                          for i, name in enumerate(res.spring_names)))

    coarse, fine_res = results[MESHES[0]], results[MESHES[1]]
    same = np.array([coarse.ei_mean[coarse.n_elements * k // fine_res.n_elements]
                     for k in range(fine_res.n_elements)])
    ci6 = coarse.credible_interval(0.95)
    ci30 = fine_res.credible_interval(0.95)
    w6 = np.repeat((ci6[:, 1] - ci6[:, 0]) / coarse.ei_mean, fine_res.n_elements // coarse.n_elements)
    w30 = (ci30[:, 1] - ci30[:, 0]) / fine_res.ei_mean
    print(f"\n{MESHES[1]} vs {MESHES[0]} elements: posterior means differ by "
          f"{np.sqrt(np.mean((fine_res.ei_mean / same - 1.0) ** 2)):.1%} rms; relative 95 % width "
          f"{w30.mean():.2f} vs {w6.mean():.2f} on average (wider on the finer mesh in "
          f"{np.mean(w30 > w6):.0%} of the 1 m elements)")

    for n, res in results.items():
        fig, ax = new_figure((9, 3.8))
        plot_ei_posterior(res, ax=ax, supports=supports, truth=(fine.mesh.edges, fine.ei))
        ax.set_ylim(0.3 * NOMINAL_EI, 1.9 * NOMINAL_EI)  # the truth stairs start from a zero baseline
        ax.set_title(f"openLAB-like frame: EI from {N_CROSSINGS} synthetic crossings, {n} elements")
        print("figure:", save_figure(fig, Path(out) / f"inversion_openlab_{n}el.png"))
    fig, axes = new_figure((11, 3.4 * len(MESHES)), len(MESHES), 2)
    for row, (n, res) in zip(axes, results.items()):
        for i, ax in enumerate(row):
            plot_fit(res, i, ax=ax)
            ax.set_title(f"{res.sensor_names[i]}: data vs model, {n} elements")
    print("figure:", save_figure(fig, Path(out) / "inversion_openlab_fit.png"))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="studies/output")
    main(parser.parse_args().out)
