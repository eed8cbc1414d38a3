"""The feasible sets of every branch as an SVG strip chart, drawn under the viewer's parameter slider.

One row per branch over the parameter's range (−π, π] (rad, left to right, as the slider): the
exact feasible intervals of :func:`qpik.feasible_intervals` as green bars, the values where a joint
is singular as grey ticks, the slider's value as a blue line across the rows and the best answer of
:func:`qpik.solve_best` as a gold dot on its branch's row.
"""

from __future__ import annotations

import math
from html import escape

from qpik.analytic import FeasibleIntervals

WIDTH = 290  # px, the whole chart
LABEL = 34  # px, the branch labels' column
ROW = 13  # px per branch
TOP = 4  # px above the first row
AXIS = 14  # px below the last row, for the tick labels
FEASIBLE, TRACK, CURSOR, BEST, SINGULAR = "#2f9e44", "#e9ecef", "#1c7ed6", "#f08c00", "#868e96"


def x_of(value: float) -> float:
    """Horizontal position (px) of a parameter value (rad, in [−π, π])."""
    return LABEL + (value + math.pi) / (2 * math.pi) * (WIDTH - LABEL - 2)


def feasible_chart(
    intervals: FeasibleIntervals, param: float, best: tuple[int, float] | None = None, symbol: str = "ψ"
) -> str:
    """The chart as an ``<svg>`` element.

    Args:
        intervals: every branch's feasible sets.
        param: the slider's value, rad.
        best: ``(branch id, parameter in rad)`` of the best answer, or None.
        symbol: the parameter's name in the axis labels.
    """
    rows = len(intervals.branch)
    height = TOP + rows * ROW + AXIS
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH}" height="{height}" font-family="sans-serif"'
           ' font-size="9">']  # fmt: skip
    for r, (b, sets) in enumerate(zip(intervals.branch.tolist(), intervals.intervals)):
        y = TOP + r * ROW
        out.append(f'<text x="2" y="{y + ROW - 4}" fill="#495057">b{b}</text>')
        out.append(f'<rect x="{LABEL}" y="{y + 2}" width="{WIDTH - LABEL - 2}" height="{ROW - 4}" fill="{TRACK}"/>')
        for lo, hi in sets:
            x0, x1 = x_of(lo), x_of(hi)
            out.append(f'<rect class="feasible" data-branch="{b}" data-lo="{lo!r}" data-hi="{hi!r}"'
                       f' x="{x0:.2f}" y="{y + 2}" width="{max(x1 - x0, 1.0):.2f}" height="{ROW - 4}"'
                       f' fill="{FEASIBLE}"/>')  # fmt: skip
        for s in intervals.singular[r] if r < len(intervals.singular) else ():
            out.append(f'<line x1="{x_of(s):.2f}" x2="{x_of(s):.2f}" y1="{y + 1}" y2="{y + ROW - 1}"'
                       f' stroke="{SINGULAR}"/>')  # fmt: skip
        if best is not None and best[0] == b:
            out.append(f'<circle class="best" cx="{x_of(best[1]):.2f}" cy="{y + ROW / 2}" r="3.5" fill="{BEST}"'
                       ' stroke="#fff"/>')  # fmt: skip
    bottom = TOP + rows * ROW
    xc = x_of(param)
    out.append(f'<line class="cursor" x1="{xc:.2f}" x2="{xc:.2f}" y1="{TOP}" y2="{bottom}" stroke="{CURSOR}"'
               ' stroke-width="1.5"/>')  # fmt: skip
    sym = escape(symbol)
    for value, text in ((-math.pi, "−π"), (0.0, f"{sym} = 0"), (math.pi, "π")):
        anchor = "start" if value < 0 else "end" if value > 0 else "middle"
        out.append(f'<text x="{x_of(value):.2f}" y="{bottom + 10}" text-anchor="{anchor}" fill="#868e96">{text}</text>')
    out.append("</svg>")
    return "".join(out)
