"""The run's picture explains itself: a title saying what was run, stations and fixed blocks marked, axes with
units, and the runs compared on shared axes."""

from dataclasses import replace

import pytest

from cbtc.layout_files import load_layout
from cbtc.zone.config import paper_scenario

pytest.importorskip("matplotlib")


def test_the_comparison_picture_names_the_run_marks_stations_and_blocks_and_shares_its_axes(tmp_path):
    from cbtc.experiments.plots import distance_time_figure, distance_time_png
    from cbtc.sim.simulation import Simulation

    base = paper_scenario(load_layout("itb_square"), seed=3, laps=None, duration_s=15.0)
    runs = [Simulation(replace(base, policy=policy), keep_samples=True).run() for policy in ("fixed_block",
                                                                                            "moving_block")]
    fig = distance_time_figure(runs, ["fixed block (baseline)", "moving block + Takagi control"])
    assert fig._suptitle.get_text() == "paper scenario: 2 trains on itb_square, seed 3"
    (fixed_top, moving_top), (fixed_gap, moving_gap) = fig.axes[0:2], fig.axes[2:4]
    assert fixed_top.get_shared_y_axes().joined(fixed_top, moving_top)
    assert fixed_top.get_shared_x_axes().joined(fixed_top, moving_gap)
    assert fixed_gap.get_shared_y_axes().joined(fixed_gap, moving_gap)
    assert fixed_top.get_ylabel() == "head position along the loop (m)" and fixed_gap.get_xlabel() == "time (s)"
    assert fixed_gap.get_ylabel().endswith("(m)")
    layout = base.layout

    def levels(ax):
        return {round(line.get_ydata()[0], 6) for line in ax.get_lines() if len(set(line.get_ydata())) == 1}
    stations = {round(st.s_m, 6) for st in layout.stations}
    blocks = {round(b.start_m, 6) for b in layout.blocks}
    assert stations <= levels(fixed_top) and stations <= levels(moving_top)
    assert blocks <= levels(fixed_top) and not (blocks - stations) & levels(moving_top)   # blocks: fixed block only
    names = {text.get_text() for text in fixed_top.texts}
    assert {st.name for st in layout.stations} <= names
    legend = [text.get_text() for text in fixed_top.get_legend().get_texts()]
    assert "station" in legend and "block boundary" in legend and "train A" in legend
    path = distance_time_png(runs[1:], str(tmp_path / "run.png"))
    assert open(path, "rb").read(8) == b"\x89PNG\r\n\x1a\n"
