"""Figures of a run: the train graph (each head's position along the track against time, stations and fixed blocks
marked, as a timetable planner draws it) and the gap to the train ahead below it. matplotlib with the Agg backend."""

import os
import textwrap

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cbtc.zone.factory import policy_class


def run_title(config, policy=True) -> str:
    """What was run, in words: the scenario (and its file), the trains, the layout, the policy (unless `policy` is
    False: the runs compared differ in it) and the seed."""
    source = config.source and os.path.basename(config.source)
    what = f"scenario {config.name}" + (f" ({source})" if source and source != config.name else "") \
        if config.name else "paper scenario" if len(config.trains) == 2 and not config.faults else "simulation"
    faults = f", faults: {', '.join(f.name for f in config.faults)}" if config.faults else ""
    how = f", {policy_class(config.policy).title}" if policy else ""
    return f"{what}: {len(config.trains)} trains on {config.layout.name}{how}, seed {config.seed}{faults}"


def _on_the_line(layout, head_s_m):
    """Head positions with a gap (NaN) where a train crosses the loop's seam, so no line is drawn across the plot."""
    s = np.asarray(head_s_m, dtype=float)
    if not layout.closed or len(s) < 2:
        return s
    out = s.copy()
    out[1:][np.abs(np.diff(s)) > layout.length_m / 2] = np.nan
    return out


def distance_time_png(recorders, path, titles=None, paper_note=None):
    """distance_time_figure written to the PNG `path`."""
    fig = distance_time_figure(recorders, titles, paper_note)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def distance_time_figure(recorders, titles=None, paper_note=None):
    """One column per run (`titles` names each, by default its policy; the figure's title says what was run): the
    train graph above, the gap head to tail below; every column on the same axes, so runs compare at a glance."""
    titles = titles or [rec.sim.policy.title for rec in recorders]
    fig, axes = plt.subplots(2, len(recorders), figsize=(6.5 * len(recorders), 7.5), squeeze=False, sharex=True,
                             sharey="row", gridspec_kw={"height_ratios": [3, 2]})
    for col, (rec, title) in enumerate(zip(recorders, titles)):
        top, bottom = axes[0][col], axes[1][col]
        layout = rec.layout
        t = np.asarray(rec.t_s)
        blocks = rec.sim.policy.blocks(layout)
        for k, block in enumerate(blocks):
            top.axhline(block.start_m, color="0.6", lw=0.7, ls=":", label="block boundary" if k == 0 else None)
        for k, station in enumerate(layout.stations):
            top.axhline(station.s_m, color="0.35", lw=0.8, ls="--", label="station" if k == 0 else None)
            top.annotate(station.name, (1.0, station.s_m), xycoords=("axes fraction", "data"), xytext=(3, 0),
                         textcoords="offset points", va="center", fontsize=8, color="0.25")
        for i, train in enumerate(rec.sim.trains):
            top.plot(t, _on_the_line(layout, rec.head_s_m[i]), lw=1.2, label=f"train {train.train_id}")
            if rec.gap_m[i]:
                bottom.plot(t, rec.gap_m[i], lw=1.0, label=f"train {train.train_id}")
        top.set_title(title, fontsize=10)
        top.set_ylim(0.0, layout.length_m)
        top.grid(True, alpha=0.25)
        bottom.axhline(0.0, color="red", lw=0.8, label="contact (collision below)")
        bottom.set_xlabel("time (s)")
        bottom.grid(True, alpha=0.25)
        if col == 0:
            top.set_ylabel(f"head position along the {'loop' if layout.closed else 'line'} (m)")
            bottom.set_ylabel("gap to the train ahead,\nhead to tail (m)")
        top.legend(loc="upper left", fontsize=8, ncol=2 if len(rec.sim.trains) > 4 else 1, framealpha=0.9)
        bottom.legend(loc="upper right", fontsize=8, ncol=2 if len(rec.sim.trains) > 4 else 1, framealpha=0.9)
    one_policy = len({rec.sim.config.policy for rec in recorders}) == 1
    fig.suptitle(textwrap.fill(run_title(recorders[0].sim.config, policy=one_policy), 70 * len(recorders)),
                 fontsize=11)
    if paper_note:
        fig.text(0.5, 0.005, paper_note, ha="center", fontsize=8)
    fig.tight_layout(rect=(0.0, 0.02 if paper_note else 0.0, 1.0, 1.0))
    return fig
