"""The learning-curve figure draws one line per run of its CSV and refuses a CSV of other columns."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pytest

from agents.common import plots

ROOT = Path(__file__).resolve().parents[2]


def test_one_line_per_run_in_first_seen_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    csv_path = tmp_path / "curves.csv"
    csv_path.write_text('run,step,ep_rew_mean\n"b, seed 1",2000,-3\n"b, seed 1",1000,-5\na,1000,-9\n')
    drawn: list[list[tuple[float, float]]] = []
    labels: list[str] = []

    def keep(fig: object, path: Path, title: str | None = None) -> Path:
        for line in fig.axes[0].get_lines():  # type: ignore[attr-defined]
            drawn.append(list(zip(line.get_xdata(), line.get_ydata(), strict=True)))
            labels.append(line.get_label())
        plt.close(fig)  # type: ignore[arg-type]
        return path

    monkeypatch.setattr(plots, "save_figure", keep)
    plots.learning_curves_figure(csv_path, tmp_path / "curves.png", "t")
    assert labels == ["b, seed 1", "a"]
    assert drawn == [[(1000.0, -5.0), (2000.0, -3.0)], [(1000.0, -9.0)]]


def test_other_columns_are_refused(tmp_path: Path) -> None:
    csv_path = tmp_path / "curves.csv"
    csv_path.write_text("run,steps,reward\na,1,2\n")
    with pytest.raises(ValueError, match="columns must be run,step,ep_rew_mean"):
        plots.learning_curves_figure(csv_path, tmp_path / "curves.png", "t")


@pytest.mark.parametrize("name", ["learning_curve_ppo_campus_stereo", "learning_curve_ppo_corridor_targets"])
def test_shipped_curves_draw(tmp_path: Path, name: str) -> None:
    out = plots.learning_curves_figure(ROOT / "docs" / "images" / f"{name}.csv", tmp_path / f"{name}.png", name)
    assert out.stat().st_size > 10_000
