"""The HTML report, checked as a user sees it.

Building a report runs a recommendation, a verification and (with data) an
inversion and a diagnosis: every test here takes more than 10 s and is
marked slow.
"""

import base64
import dataclasses
import hashlib
import json
import re
import shutil
import subprocess
from html import unescape
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

import sensorplan as sp
from sensorplan.cli import main
from sensorplan.io.config import example_text
from sensorplan.report import build_report

_NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?|\bnan\b")


def numbers(text):
    return [float(x) for x in _NUMBER.findall(text)]

ARTIFACTS = Path(__file__).resolve().parents[1] / "test-artifacts"


class _Collector(HTMLParser):
    def __init__(self):
        super().__init__()
        self.h2, self.images, self.captions, self._in = [], [], [], None
        self.rows, self._cell = [], None  # table rows as lists of cell texts

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "tr":
            self.rows.append([])
        if tag in ("td", "th"):
            self._cell = ""
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        if tag in ("h2", "figcaption"):
            self._in = tag
            (self.h2 if tag == "h2" else self.captions).append("")
        if tag in ("script", "link") and (attrs.get("src") or attrs.get("href")):
            raise AssertionError(f"external resource in the report: {attrs}")

    def handle_endtag(self, tag):
        if tag == self._in:
            self._in = None
        if tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append(self._cell.strip())
            self._cell = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        if self._in == "h2":
            self.h2[-1] += data
        elif self._in == "figcaption":
            self.captions[-1] += data


def _parse(path_or_html):
    parser = _Collector()
    parser.feed(path_or_html if isinstance(path_or_html, str) else path_or_html.read_text(encoding="utf-8"))
    return parser


def _row(parsed, first):
    """The cells after the first of the (unique) table row whose first cell is ``first``
    (outside the verification table, whose cells read "mean ± se")."""
    rows = [r[1:] for r in parsed.rows if r and r[0] == first and "±" not in "".join(r)]
    assert len(rows) == 1, f"{len(rows)} rows start with {first!r}"
    return rows[0]


@pytest.fixture(scope="module")
def built_report(tmp_path_factory):
    """A report with data, built in Python so that the results it shows are at hand."""
    case = sp.example_case("openlab-like")
    data = sp.simulate_crossings(case, 3, noise=True, rng=1)
    report = build_report(case, data=data, n_scenarios=2)
    path = tmp_path_factory.mktemp("report") / "report.html"
    path.write_text(report.html, encoding="utf-8")
    return report, path


@pytest.fixture(scope="module")
def report_with_data(built_report):
    return built_report[1]


@pytest.mark.slow
def test_report_sections_and_embedded_figures(report_with_data):
    parsed = _parse(report_with_data)
    assert parsed.h2 == ["Conclusion", "Bridge and load model", "Informativeness of candidate positions",
                         "Recommended layout and certificate", "What the layout will detect",
                         "Verification by inversion of synthetic damage",
                         "Identified EI with credible bands", "Sim-to-real gap diagnosis"]
    assert len(parsed.images) >= 10
    for src in parsed.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(parsed.captions) == len(parsed.images)
    assert all("Reading guide:" in c for c in parsed.captions)


@pytest.mark.slow
def test_report_shows_the_computed_results(built_report):
    # the numbers in the HTML are those of the results the report was built from
    report, _ = built_report
    parsed = _parse(report.html)
    design, verification, posterior, diagnosis = report.design, report.verification, report.posterior, report.diagnosis
    np.testing.assert_allclose(numbers(_row(parsed, "positions [m]")[0]), design.layout_m, atol=0.005)
    assert numbers(_row(parsed, "D criterion of the layout")[0])[0] == pytest.approx(design.value, rel=1e-5)
    assert numbers(_row(parsed, "relaxation bound (no layout can do better)")[0])[0] == pytest.approx(
        design.bound, rel=1e-5)
    assert numbers(_row(parsed, "certified efficiency (a lower bound)")[0])[0] == pytest.approx(
        100 * design.efficiency, abs=0.005)
    for b in design.baselines:
        cells = _row(parsed, b.name)
        if b.feasible:
            assert numbers(cells[0])[0] == pytest.approx(b.value, rel=1e-5)
            np.testing.assert_allclose(numbers(cells[1]), b.layout_m, atol=0.005)
    # verification: one row per verified layout (recommended first), mean ± se per metric, the rates with their
    # counts and Wilson 95 % intervals, "no detections" instead of a localisation error of nan
    names = ["recommended"] + [b.name for b in design.baselines if b.feasible]
    assert len(verification.layouts) == len(names)
    metrics = ("rmse", "localisation_error_m", "detection_rate", "false_alarm_rate", "coverage95", "band_width")
    verification_rows = [r for r in parsed.rows if r and r[0] in names and "±" in "".join(r)]
    assert [r[0] for r in verification_rows] == names
    rate = re.compile(r"^(\d\.\d\d) \((\d+)/(\d+); 95 % (\d\.\d\d)-(\d\.\d\d)\)$")
    for row, score in zip(verification_rows, verification.layouts):
        for cell, key in zip(row[1:], metrics):
            m = score.metrics[key]
            if m.is_rate:
                mean, count, n, lo, hi = rate.match(cell).groups()
                assert (float(mean), int(count), int(n)) == (pytest.approx(m.mean, abs=5e-3), m.count, m.n)
                np.testing.assert_allclose([float(lo), float(hi)], m.ci95, atol=5e-3)
            elif m.n == 0:
                assert cell == "no detections"
            elif np.isnan(m.se):  # a single value: the report shows it without a standard error
                np.testing.assert_allclose(numbers(cell), [m.mean], atol=5e-4)
            else:
                np.testing.assert_allclose(numbers(cell), [m.mean, m.se], atol=5e-4)
    # the ranking by verification: every verified layout once, by detection rate (then detection limit),
    # and a plain note for each baseline ranked above the recommended layout
    rank_rows = [r for r in parsed.rows if len(r) == 7 and r[0].isdigit()]
    assert [r[0] for r in rank_rows] == [str(k) for k in range(1, len(names) + 1)]
    assert sorted(r[1] for r in rank_rows) == sorted(names)
    by_name = dict(zip(names, verification.layouts))
    keys = [(-by_name[r[1]].metrics["detection_rate"].mean, -by_name[r[1]].detection_limit) for r in rank_rows]
    assert keys == sorted(keys)
    above = [r[1] for r in rank_rows[:[r[1] for r in rank_rows].index("recommended")]]
    # one consolidated note on the ranking, naming every layout ranked above the recommended one
    notes = re.findall(r'<p class="verdict">([^<]*)</p>', report.html.split("Ranking by verification")[1])
    assert len(notes) >= 1
    for name in above:
        assert name in notes[0]
    assert bool(above) != ("The D-optimal layout verifies best." in notes[0])
    # identified EI: one row per element, mean and 95 % interval
    ci = posterior.credible_interval(0.95)
    for j, (a, b) in enumerate(zip(posterior.edges[:-1], posterior.edges[1:])):
        shown = numbers(" ".join(_row(parsed, f"{a:.2f}-{b:.2f}")))  # mean, 95 % low, high, nominal
        np.testing.assert_allclose(shown, [posterior.ei_mean[j], *ci[j], posterior.ei_nominal[j]], rtol=5e-4)
    # diagnosis: the verdict and every effect's log Bayes factor
    shown = report.html.replace("&#x27;", "'")
    assert f"Verdict ({diagnosis.verdict.status}): {diagnosis.verdict.summary}" in shown
    assert diagnosis.statement in shown
    for effect in diagnosis.effects:
        assert numbers(_row(parsed, effect.name)[0])[0] == pytest.approx(effect.log_bayes_factor, abs=0.005)


@pytest.mark.slow
@pytest.mark.parametrize("example", sp.EXAMPLES)
def test_report_on_every_example(example, tmp_path, capsys):
    assert main(["report", "--example", example, "--count", "2", "--scenarios", "2", "--out", str(tmp_path)]) == 0
    parsed = _parse(tmp_path / "report.html")
    assert parsed.h2[0] == "Conclusion" and parsed.h2[-1] == "Provenance"
    assert "Recommended layout and certificate" in parsed.h2 and "What the layout will detect" in parsed.h2
    # the layout printed on the console is the one in the report
    captured = capsys.readouterr()
    printed = captured.out
    # a progress line per stage on stderr, and the verification's count of scenario inversions
    stages = [line.split(": ", 1)[1] for line in captured.err.splitlines()]
    assert stages[0].startswith("recommending a D-optimal layout of 2 sensor(s)")
    assert stages[1].startswith("verifying the recommended layout and ")
    assert any(re.match(r"(\d+)/\1 done in ", s) for s in stages)
    assert "mapping what the layout detects along the bridge" in stages
    assert any(s.startswith("finding the fewest sensors that reach a worst-case detection power of 0.9")
               for s in stages)
    assert stages[-1] == "drawing the figures and writing the report"
    # the first sentence says whether the requirement is met, on the console and in the report
    first = printed.splitlines()[0]
    assert first.startswith(("Sufficient: ", "Not sufficient: "))
    page = (tmp_path / "report.html").read_text(encoding="utf-8")
    opening = re.search(r'<p class="conclusion[^"]*"><b>(.*?)</b>', page).group(1)
    assert unescape(opening) == first
    line = next(x for x in printed.splitlines() if x.startswith("  positions [m]: "))
    assert numbers(_row(parsed, "positions [m]")[0]) == numbers(line)


@pytest.mark.slow
def test_report_honours_exclude_and_design_json_reproduces_the_layout(tmp_path, capsys):
    config = tmp_path / "case.toml"
    config.write_text(example_text("openlab-like"), encoding="utf-8")
    args = ["report", "--config", str(config), "--count", "3", "--exclude", "14:16,0:3,27:30", "--fixed", "11",
            "--scenarios", "2", "--verify-crossings", "3", "--out", str(tmp_path / "rep")]
    assert main(args) == 0
    design = json.loads((tmp_path / "rep" / "design.json").read_text())
    layout = design["layout_m"]
    # no sensor in an excluded zone
    assert all(not (a <= x <= b) for x in layout for a, b in ((14, 16), (0, 3), (27, 30))), layout
    # provenance: version, the sha256 of the case file, every option, the command line
    record = design["provenance"]
    assert record["sensorplan_version"] == sp.__version__
    assert record["inputs"]["config"]["sha256"] == hashlib.sha256(config.read_bytes()).hexdigest()
    assert record["options"]["exclude"] == [[14.0, 16.0], [0.0, 3.0], [27.0, 30.0]]
    assert "--exclude" in record["command_line"]
    html_text = (tmp_path / "rep" / "report.html").read_text(encoding="utf-8")
    parsed = _parse(html_text)
    assert parsed.h2[0] == "Conclusion" and parsed.h2[-1] == "Provenance"
    assert "Install 3 rotation sensor(s) at x = " + ", ".join(f"{x:.2f}" for x in layout) in html_text
    assert "@media print" in html_text and "http://" not in html_text and "https://" not in html_text
    assert record["inputs"]["config"]["sha256"] in html_text
    capsys.readouterr()
    # rerunning recommend from design.json gives the same layout
    again = tmp_path / "again.json"
    assert main([*design["recommend_argv"], "--out", str(tmp_path / "again"), "--json", str(again), "--quiet"]) == 0
    assert json.loads(again.read_text())["layout_m"] == layout


@pytest.mark.slow
def test_conclusion_says_plainly_when_a_baseline_verified_better(built_report):
    from sensorplan.analysis import Analysis
    from sensorplan.report import better_baselines
    from sensorplan.verification.results import Metric

    report, _ = built_report
    v = report.verification
    rec = v.layouts[0]
    # a baseline that detects every loss the recommended layout misses (mean 1, se 0) beats it plainly
    boosted = dataclasses.replace(v.layouts[1], metrics={**v.layouts[1].metrics,
                                                         "detection_rate": Metric(1.0, 0.0)})
    worse = dataclasses.replace(rec, metrics={**rec.metrics, "detection_rate": Metric(0.0, 0.0)})
    verification = dataclasses.replace(v, layouts=(worse, boosted, *v.layouts[2:]))
    analysis = Analysis(None, None, report.design, verification)
    name = [b.name for b in report.design.baselines if b.feasible][0]
    assert [n for n, _ in better_baselines(analysis)][0] == name
    page = render_report_conclusion(analysis)
    assert "A baseline verified better than the recommended layout" in page and name in page
    same = Analysis(None, None, report.design, dataclasses.replace(v, layouts=(rec, rec, *v.layouts[2:])))
    assert better_baselines(same) == []


def render_report_conclusion(analysis):
    from sensorplan.report.conclusion import conclusion_html

    return conclusion_html(analysis)


def _browser():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.mark.slow
def test_report_renders_in_headless_chromium(report_with_data, tmp_path):
    browser = _browser()
    if browser is None:
        pytest.skip("no Chromium on this machine (.ci/run installs it from Debian packages)")
    flags = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
             "--disable-background-networking", "--disable-component-update", "--disable-sync",
             f"--user-data-dir={tmp_path / 'profile'}", "--virtual-time-budget=10000"]
    url = report_with_data.resolve().as_uri()
    dom = subprocess.run([browser, *flags, "--dump-dom", url], capture_output=True, text=True, timeout=180)
    n_images = len(_parse(report_with_data).images)
    match = re.search(r'data-images-loaded="(\d+)/(\d+)"', dom.stdout)
    assert match, dom.stderr[-2000:]
    assert int(match.group(1)) == int(match.group(2)) == n_images
    ARTIFACTS.mkdir(exist_ok=True)
    shot = ARTIFACTS / "report.png"
    subprocess.run([browser, *flags, "--window-size=1200,4000", f"--screenshot={shot}", url],
                   capture_output=True, timeout=180)
    assert shot.exists() and shot.read_bytes()[:4] == b"\x89PNG"
