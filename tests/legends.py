"""What a figure's legends explain, read from the matplotlib objects (not the pixels).

- :func:`missing_labels`: the labels of drawn artists (lines, patches, collections) that no legend of the
  figure shows;
- :func:`unexplained`: drawn artists whose style no legend entry shows: a line whose (line style, marker)
  pair, a patch or collection whose face colour, is not that of any legend entry (a colour of a line entry
  explains bars of that colour, e.g. a branch's feasible set).

Use both: a figure passes when every label is in a legend and every style is one the legends name.
"""

from __future__ import annotations

from matplotlib.collections import Collection
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch


def _legends(fig: Figure) -> list:
    out = list(fig.legends)
    for ax in fig.axes:
        if ax.get_legend() is not None:
            out.append(ax.get_legend())
    return out


def _drawn(fig: Figure) -> list:
    """Lines with data, patches and collections of every axes (an empty proxy line is a legend entry, not a mark)."""
    out = []
    for ax in fig.axes:
        out += [ln for ln in ax.lines if len(ln.get_xdata()) and ln.get_visible()]
        out += [p for p in ax.patches if p.get_visible()]
        out += [c for c in ax.collections if c.get_visible()]
    return out


def missing_labels(fig: Figure) -> set[str]:
    """Labels of artists of ``fig`` that are not shown in any of its legends."""
    shown = {t.get_text() for lg in _legends(fig) for t in lg.get_texts()}
    labels = set()
    for ax in fig.axes:
        for artist in [*ax.lines, *ax.patches, *ax.collections]:
            label = artist.get_label()  # None or "_..." : not for a legend
            if label and not str(label).startswith("_"):
                labels.add(label)
    return labels - shown


def _rgb(color) -> tuple[float, ...]:
    return tuple(round(v, 3) for v in to_rgb(color))


def unexplained(fig: Figure) -> list[str]:
    """Descriptions of the drawn artists whose style no legend entry of ``fig`` shows (see the module docstring)."""
    styles, colours = set(), set()
    for lg in _legends(fig):
        for h in lg.legend_handles:
            if isinstance(h, Line2D):
                styles.add((h.get_linestyle(), h.get_marker() or "None"))
                colours.add(_rgb(h.get_color()))
            elif isinstance(h, Patch):
                colours.add(_rgb(h.get_facecolor()))
            elif isinstance(h, Collection) and len(h.get_facecolor()):
                colours.add(_rgb(h.get_facecolor()[0]))
    out = []
    for artist in _drawn(fig):
        if isinstance(artist, Line2D):
            style = (artist.get_linestyle(), artist.get_marker() or "None")
            if style not in styles:
                out.append(f"line {style} in {artist.axes.get_title()!r}")
        elif isinstance(artist, Patch):
            if _rgb(artist.get_facecolor()) not in colours:
                out.append(f"patch {_rgb(artist.get_facecolor())} in {artist.axes.get_title()!r}")
        elif len(artist.get_facecolor()) and any(_rgb(c) not in colours for c in artist.get_facecolor()):
            out.append(f"collection {[_rgb(c) for c in artist.get_facecolor()]} in {artist.axes.get_title()!r}")
    return out
