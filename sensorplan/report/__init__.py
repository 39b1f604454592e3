"""Self-contained HTML report: model, informativeness, layout, verification, identification, gap.

Figures are embedded as base64 PNG, styles inline, no network needed to
view the file.  Every figure carries a one-sentence reading guide.

Owns: :class:`Report`, :func:`build_report`, :func:`render_report` and
:func:`provenance`; the page's HTML kit (``page``), its conclusion
(``conclusion``) and its sections (``sections``).
May import: plotting, analysis and the layers below (it renders their results).
"""

from dataclasses import KW_ONLY, dataclass, field

from .conclusion import better_baselines, conclusion_html
from .page import render_page
from .record import provenance, provenance_section
from .sections import (
    design_section,
    detectability_section,
    gap_section,
    identification_section,
    informativeness_section,
    model_section,
    verification_section,
)

__all__ = ["build_report", "render_report", "Report", "provenance"]


@dataclass(frozen=True, eq=False)
class Report:
    """The HTML text and the results it was built from."""

    html: str
    sections: tuple
    _: KW_ONLY
    design: object = None
    verification: object = None
    posterior: object = None
    diagnosis: object = None
    figures: tuple = field(default_factory=tuple)


def build_report(case, **options):
    """:func:`render_report` of :func:`sensorplan.analysis.analyse` (``options`` go to ``analyse``)."""
    from ..analysis import analyse

    return render_report(analyse(case, **options))


def render_report(analysis, *, provenance=None):
    """Render an :class:`~sensorplan.analysis.Analysis` as one self-contained HTML page.

    ``provenance`` (from :func:`provenance`) adds the provenance section.
    """
    sections = [("Conclusion", f'<p class="{_conclusion_class(analysis)}">{conclusion_html(analysis)}</p>'), model_section(analysis.case),
                informativeness_section(analysis), design_section(analysis)]
    if analysis.detectability is not None:
        sections.append(detectability_section(analysis.detectability))
    sections.append(verification_section(analysis))
    if analysis.posterior is not None:
        sections += [identification_section(analysis), gap_section(analysis)]
    if provenance is not None:
        sections.append(provenance_section(provenance))
    return Report(render_page(analysis.case, sections), tuple(title for title, _ in sections), design=analysis.design,
                  verification=analysis.verification, posterior=analysis.posterior, diagnosis=analysis.diagnosis)


def _conclusion_class(analysis):
    """The conclusion's box: green only when the requirement is met and the data (if any) show no change."""
    met = analysis.target is not None and analysis.target.answer.met and (
        analysis.target.answer.count <= analysis.design.count)
    calm = analysis.verdict is None or analysis.verdict.status == "no_change"
    return "conclusion" if met and calm else "conclusion warn"
