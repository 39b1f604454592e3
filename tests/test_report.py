"""The HTML report, checked as a user sees it."""

import base64
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

from sensorplan.io.config import EXAMPLES
from sensorplan.cli import main

ARTIFACTS = Path(__file__).resolve().parents[1] / "test-artifacts"


class _Collector(HTMLParser):
    def __init__(self):
        super().__init__()
        self.h2, self.images, self.captions, self._in = [], [], [], None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
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

    def handle_data(self, data):
        if self._in == "h2":
            self.h2[-1] += data
        elif self._in == "figcaption":
            self.captions[-1] += data


def _parse(path):
    parser = _Collector()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser


@pytest.fixture(scope="module")
def report_with_data(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    data = out / "data.csv"
    assert main(["simulate", "--example", "openlab-like", "--crossings", "3", "--noise", "--seed", "1",
                 "--out", str(data), "--quiet"]) == 0
    assert main(["report", "--example", "openlab-like", "--data", str(data), "--scenarios", "2",
                 "--out", str(out), "--quiet"]) == 0
    return out / "report.html"


def test_report_sections_and_embedded_figures(report_with_data):
    parsed = _parse(report_with_data)
    assert parsed.h2 == ["Bridge and load model", "Informativeness of candidate positions",
                         "Recommended layout and certificate", "Verification by inversion of synthetic damage",
                         "Identified EI with credible bands", "Sim-to-real gap diagnosis"]
    assert len(parsed.images) >= 10
    for src in parsed.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(parsed.captions) == len(parsed.images)
    assert all("Reading guide:" in c for c in parsed.captions)


@pytest.mark.parametrize("example", EXAMPLES)
def test_report_on_every_example(example, tmp_path):
    assert main(["report", "--example", example, "--count", "2", "--scenarios", "2", "--out", str(tmp_path),
                 "--quiet"]) == 0
    parsed = _parse(tmp_path / "report.html")
    assert len(parsed.h2) == 4 and "Recommended layout and certificate" in parsed.h2


def _browser():
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


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
