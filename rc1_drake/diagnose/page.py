"""The diagnosis as one self-contained HTML page (`rc1 diagnose --report DIR`): the answer first, the error
waterfall, each round's ranking, where the final model still fails per case, the model file, and the command that
reproduces it. Figures are embedded as PNG data, so the page opens anywhere, offline."""

import base64
import html
import io
from pathlib import Path

from ..plots import candidates_figure, compare_figures, waterfall_figure

VERDICT_COLOURS = {
    "effect_found": "#2e7d32",
    "no_missing_effect": "#1565c0",
    "ambiguous": "#ef6c00",
    "unexplained": "#c62828",
}
STYLE = """body{font-family:sans-serif;margin:2em auto;max-width:1100px;color:#222}
.verdict{color:#fff;padding:0.8em 1.2em;border-radius:6px;font-size:1.2em}
.summary{font-size:1.05em;line-height:1.6}
pre{background:#f5f5f5;padding:0.8em;font-size:0.8em;white-space:pre-wrap;overflow-wrap:anywhere}
img{max-width:100%;display:block;margin:0.5em 0}"""


def _image(fig, alt: str) -> str:
    import matplotlib.pyplot as plt  # after ..plots, which chose the backend

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=90)
    plt.close(fig)
    data = base64.b64encode(buffer.getvalue()).decode()
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def report_page(diagnosis, campaign, *, model_yaml: str, command: str) -> str:
    """The page's HTML for `diagnosis` (a Diagnosis with its final CampaignReport) of `campaign`."""
    verdict, *summary = diagnosis.summary()
    colour = VERDICT_COLOURS.get(str(diagnosis.verdict), "#444")
    parts = [
        f'<div class="verdict" id="verdict" style="background:{colour}">{html.escape(verdict)}</div>',
        '<div class="summary">' + "<br>".join(html.escape(line) for line in summary) + "</div>",
        "<h2>What each step bought</h2>",
    ]
    if diagnosis.waterfall:
        parts.append(_image(waterfall_figure(diagnosis.waterfall), "error waterfall"))
    if diagnosis.candidates:
        parts.append(_image(candidates_figure(diagnosis.candidates), "candidates' held-out gains"))
    for k, r in enumerate(diagnosis.rounds):
        parts += [f"<h2>Round {k + 1}: candidates against {html.escape(r.baseline.label)}</h2>"]
        parts.append(f"<pre>{html.escape(r.table())}</pre>")
    if diagnosis.report is not None:
        parts.append("<h2>Where the final model still fails</h2>")
        for case, figures in compare_figures(diagnosis.report, campaign).items():
            parts.append(f"<h3>{html.escape(case)}</h3>")
            parts += [_image(fig, name) for name, fig in figures.items()]
    parts += [
        "<h2>The model file</h2>",
        f"<pre>{html.escape(model_yaml)}</pre>",
        "<h2>To reproduce</h2>",
        f"<pre>{html.escape(command)}</pre>",
        "<h2>The whole report</h2>",
        f"<pre>{html.escape(diagnosis.format())}</pre>",
    ]
    title = html.escape(f"rc1 diagnose {Path(diagnosis.campaign).name}: {diagnosis.verdict}")
    head = f'<head><meta charset="utf-8"><title>{title}</title><style>{STYLE}</style></head>'
    body = f"<h1>{title}</h1>\n" + "\n".join(parts)
    return f'<!DOCTYPE html>\n<html lang="en">{head}<body>\n{body}\n</body></html>\n'
