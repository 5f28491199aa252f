"""Figures at print quality. The names of the files a command writes into a folder are known here before anything
is drawn, so that ``main`` checks each of them at the edge (:func:`ultraglide.apps.cli.options.output_option`)."""

# ``model --plots DIR``: the paper's figures 2-9, each a PNG (300 dpi) and a PDF
PAPER_FIGURES = ("fig2-lateral-stick-slip", "fig3-glide-threshold", "fig4-detach-amplitude", "fig5-reaction-force",
                 "fig6-friction-force", "fig7-friction-coefficient", "fig8-relative-friction",
                 "fig9-model-comparison")
# an experiment's session folder: the staircase's track and the psychometric function, each a PNG and a PDF
SESSION_FIGURES = ("track", "psychometric")


def both_formats(stems) -> tuple[str, ...]:
    """The files a figure of each stem is written as: ``STEM.png`` and ``STEM.pdf``."""
    return tuple(f"{stem}.{suffix}" for stem in stems for suffix in ("png", "pdf"))
