"""The paper's Figure 3 for one train: encoder prediction, IPS and the UKF against the truth, in the plane and over
time."""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

# method key -> (legend, matplotlib style)
_STYLE = {
    "dead_reckoning": ("encoder prediction (dead reckoning)", dict(color="tab:orange", lw=1.0)),
    "ips": ("IPS fixes", dict(color="tab:green", marker=".", ls="none", ms=3, alpha=0.6)),
    "ukf_enc_ips": ("UKF encoder + IPS", dict(color="tab:blue", lw=1.0)),
    "ukf_enc_ips_rfid": ("UKF encoder + IPS + RFID", dict(color="tab:red", lw=1.0)),
}


def fusion_png(layout, traces, train_id, path, title):
    """Left: the track (truth lies on it) with each method's positions; right: |along-track error| over time (log)."""
    fig, (plane, errors) = plt.subplots(1, 2, figsize=(13, 5.5))
    s = np.linspace(0.0, layout.length_m, 2000, endpoint=not layout.closed)
    track = layout.xy(s)
    plane.plot(track[:, 0], track[:, 1], color="0.6", lw=4, alpha=0.5, label="track (truth lies on it)")
    for key, (label, style) in _STYLE.items():
        trace = traces[train_id][key]
        plane.plot(trace.x_m, trace.y_m, label=label, **style)
        err = np.maximum(np.abs(np.asarray(trace.along_err_m)), 1e-5)
        errors.plot(trace.t_s, 100.0 * err, label=label, **style)
    for tag in layout.tags:
        x, y = layout.xy(tag.s_m)
        plane.plot(float(x), float(y), marker="s", color="k", ms=4, ls="none")
    plane.plot([], [], marker="s", color="k", ms=4, ls="none", label="RFID tags")
    plane.set_aspect("equal")
    plane.set_xlabel("x (m)")
    plane.set_ylabel("y (m)")
    plane.set_title(f"train {train_id}: positions in the layout frame")
    plane.grid(True, alpha=0.3)
    plane.legend(loc="best", fontsize=8)
    errors.set_yscale("log")
    errors.set_xlabel("time (s)")
    errors.set_ylabel("|along-track error| (cm)")
    errors.set_title(f"train {train_id}: error against truth")
    errors.grid(True, which="both", alpha=0.3)
    errors.legend(loc="upper left", fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
