"""The HandSplice page: one layout built per browser session.

``create_app()`` is what the Bokeh server calls for every new session, so each
tab gets its own :class:`webapp.state.Session` and widgets.
"""

from __future__ import annotations

import panel as pn

from webapp import config

pn.extension(notifications=False)


def _samples_table(cfg: config.AppConfig) -> pn.viewable.Viewable:
    pairs = cfg.samples()
    if not pairs:
        return pn.pane.Alert(f"No sample pairs found in {cfg.sample_dir}/samples.json yet.",
                             alert_type="warning")
    rows = "\n".join(f"| {p.name} | {p.body.name} | {p.hand.name} | {p.side} | {p.description} |"
                     for p in pairs)
    return pn.pane.Markdown("| pair | body take | hand take | side | about |\n|---|---|---|---|---|\n"
                            + rows)


def create_app() -> pn.viewable.Viewable:
    """Build the page for one browser session."""
    cfg = config.get()
    return pn.Column(
        pn.pane.Markdown("# HandSplice\nPut separately captured hand motion onto full-body "
                         "motion capture."),
        pn.pane.Markdown("## Sample pairs"),
        _samples_table(cfg),
        sizing_mode="stretch_width",
        css_classes=["hs-app"],
    )


def warm_up(cfg: config.AppConfig) -> None:
    """Precompute what the demo pair needs so the first page load is fast."""
    return None
