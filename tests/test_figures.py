"""Figures as a reader sees them: engineering units, nothing clipped, legends off the data, empty panels
explained, and step curves that do not fall to 0 at the bridge ends."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from matplotlib.backends.backend_agg import FigureCanvasAgg

import sensorplan as sp
from sensorplan import plotting
from sensorplan.model.fisher import fisher_blocks

matplotlib.use("Agg")


def _draw(fig):
    """Lay the figure out and draw it as savefig would (its layout engine included); returns the renderer."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def _outside(fig):
    """How far (inches, left, bottom, right, top) what the figure draws reaches past its edges (0 when not)."""
    tight, box = fig.get_tightbbox(_draw(fig)), fig.bbox_inches
    return [round(max(0.0, d), 2) for d in (box.x0 - tight.x0, box.y0 - tight.y0, tight.x1 - box.x1,
                                            tight.y1 - box.y1)]


@pytest.fixture(scope="module")
def case():
    return sp.example_case("openlab-like")


def test_posterior_std_steps_do_not_fall_to_zero_at_the_supports(case):
    design = sp.recommend(case, 2, "D", curve_max=0, n_random=5, grid=sp.CandidateGrid(spacing=1.0))
    ax = plotting.plot_posterior_std(design)
    steps = [p for p in ax.patches if isinstance(p, matplotlib.patches.StepPatch)]
    assert steps and all(p.get_data().baseline is None for p in steps)  # an open step line, not closed to 0
    assert min(float(np.min(p.get_data().values)) for p in steps) > 1.0  # every element keeps > 1 % std
    assert _outside(ax.figure) == [0, 0, 0, 0]


def test_informativeness_legend_sits_off_the_curves(case):
    blocks = fisher_blocks(case, sensors=sp.SensorLayout.candidates(np.linspace(0, 30, 9), "rotation",
                                                                    noise_std=[5e-6] * 9), parameterisation="ei")
    ax = plotting.plot_informativeness(blocks, supports=case.bridge.support_positions, ei=case.ei)
    fig = ax.figure
    _draw(fig)
    legend = ax.get_legend().get_window_extent()
    assert legend.x0 >= ax.get_window_extent().x1  # right of the axes, covering no curve
    assert _outside(fig) == [0, 0, 0, 0]


def test_fit_readings_in_engineering_units(case):
    data = sp.simulate_crossings(case, 2, noise=True, rng=2)
    post = sp.invert(case, data, detect=False)
    ax = plotting.plot_fit(post, "PE1")  # no kind given: the posterior knows its sensors' kinds
    assert ax.get_ylabel() == "PE1 reading [µrad]"
    assert np.max(np.abs(ax.lines[0].get_ydata())) > 1.0  # µrad, not rad


def test_shrinkage_in_noise_units_with_the_legend_off_the_bars():
    effects = [SimpleNamespace(name=n, rms_after=r, heldout_rms_after=h)
               for n, r, h in (("vertical_support_spring", 5.1e-6, 5.2e-6), ("sensor_gain", 9.5e-6, None))]
    diagnosis = SimpleNamespace(effects=effects, gap=SimpleNamespace(rms_residual=1e-5, noise_rms=5e-6))
    ax = plotting.plot_shrinkage(diagnosis)
    assert ax.get_ylabel() == "residual rms [noise rms]"
    heights = [p.get_height() for p in ax.patches]
    assert heights[:2] == pytest.approx([5.1 / 5, 9.5 / 5]) and heights[2] == pytest.approx(5.2 / 5)
    assert _outside(ax.figure) == [0, 0, 0, 0]
