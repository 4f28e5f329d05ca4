"""matplotlib for the figure writers (plot, the studies, the hard-case matrix, the reproduction scripts):
imported when a figure is drawn, never by a run (it takes ~0.5 s and a run draws nothing)."""


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib    # deferred on purpose: heavy, and only figure writers need it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def legend(ax, **kw):
    """The axes' legend where something in them has a label (matplotlib warns on stderr otherwise: a study whose
    runs gave nothing to plot printed "No artists with labels found to put in legend", issue 47)."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(**kw)
