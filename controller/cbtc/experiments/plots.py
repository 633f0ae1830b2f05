"""Figures: distance-time diagrams (the paper's Figure 4) and gap over time. matplotlib with the Agg backend."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def distance_time_png(recorders, titles, path, paper_note=None):
    """One column per run: cumulative distance of every train against time, and the true gap below it."""
    fig, axes = plt.subplots(2, len(recorders), figsize=(6.5 * len(recorders), 7), squeeze=False, sharex="col")
    for col, (rec, title) in enumerate(zip(recorders, titles)):
        top, bottom = axes[0][col], axes[1][col]
        for i, train in enumerate(rec.sim.trains):
            top.plot(rec.t_s, rec.travelled_m[i], label=f"train {train.train_id}")
            if rec.gap_m[i]:
                bottom.plot(rec.t_s, rec.gap_m[i], label=f"{train.train_id} to the train ahead")
        top.set_title(title)
        top.set_ylabel("distance travelled (m)")
        top.grid(True, alpha=0.3)
        top.legend(loc="upper left")
        bottom.set_xlabel("time (s)")
        bottom.set_ylabel("gap head to tail (m)")
        bottom.axhline(0.0, color="red", lw=0.8)
        bottom.grid(True, alpha=0.3)
        bottom.legend(loc="upper right", fontsize=8)
    if paper_note:
        fig.text(0.5, 0.005, paper_note, ha="center", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
