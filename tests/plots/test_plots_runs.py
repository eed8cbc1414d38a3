"""Pictures of closed-loop runs (qpik.plots.runs): every line, shading and marker of a run's figure is named."""

from __future__ import annotations

import numpy as np
from legends import missing_labels, unexplained

import qpik
from qpik.geometry import Sphere
from qpik.plots import runs
from qpik.sim import SimOptions, simulate


def test_the_run_figures_name_every_mark(monkeypatch, tmp_path):
    robot = qpik.load_robot("iiwa14")
    target = robot.fk(robot.q_home + 0.1)
    log = simulate(
        robot,
        lambda t, q: np.full(robot.dof, 0.2),
        robot.q_home,
        0.05,
        0.01,
        obstacles=[Sphere((0.5, 0.3, 0.6), 0.08)],
        target=target,
        options=SimOptions(d_safe=0.03),
    )
    figures = []
    monkeypatch.setattr(runs, "save", lambda fig, path, dpi=100: figures.append(fig))
    runs.plot_log(log, tmp_path / "log.png")
    runs.plot_comparison([log, log], tmp_path / "errors.png")
    for fig in figures:
        assert not missing_labels(fig) and not unexplained(fig)
    log_figure = figures[0]
    labels = {t.get_text() for ax in log_figure.axes if ax.get_legend() for t in ax.get_legend().get_texts()}
    assert {"beyond the limits", "contact (0 m)", "d_s = 0.03 m"} <= labels
