"""Where a UKF estimator places a train it has not located: at its first balise read, or where the IPS's fixes
agree, fused with a position an operator declared when the two agree, the placement covering the reference's lasting
bias (and any doubt kept from before a fresh start) until a second, independent reference confirms it."""

from math import hypot, sqrt

from cbtc.estimation.estimate import declared_at, span_offsets_m
from cbtc.estimation.track_ukf import TrackUkf
from cbtc.estimation.ukf_history import FilterState
from cbtc.estimation.ukf_model import initial_covariance, tag_read_model
from cbtc.railway.geometry import circular_offset_m


def placement(est, event):
    """(the FilterState, its TrackUkf) when `event` places the unlocated train of `est` (a UkfEstimator): its
    first tag read, or the IPS where `locate_fixes` fixes agree (encoder reports and ranges alone cannot); None when it
    does not. Either placement is pending (`confirmed`) until a second, independent reference agrees. Every IPS event
    up to this one is one of those fixes (the train is unlocated)."""
    if event.kind in ("odo", "range", "roll", "step"):
        return None
    odometer = odometer_at(est._events, event.t_s)
    if odometer is None:   # no encoder report kept yet to place it against
        return None
    d_m, v_mps = odometer
    placed = _at_tag(est, event, v_mps) if event.kind == "tag" else _at_fixes(est, event, d_m)
    if placed is None:
        return None
    used, s_m, sigma_s_m, d_m = placed
    with_scale = est._scale_sigma0 > 0
    sigma_v_mps = 0.05 + 0.1 * abs(v_mps)
    top_mps = est._wheel.top_mps
    if not 0.0 <= v_mps <= top_mps:
        # the odometer moved faster than the motor can drive (a count that caught up after sticking, a burst):
        # not the train's speed; it starts anywhere in what the train can do
        v_mps, sigma_v_mps = min(max(v_mps, 0.0), top_mps), top_mps
    x0 = [est.layout.wrap(s_m), v_mps, d_m] + ([0.0] if with_scale else [])
    P0 = initial_covariance(len(x0), sigma_s_m, sigma_v_mps, 0.002, est._scale_sigma0)
    filt = TrackUkf(est.layout, est.noise, x0, P0, event.t_s)
    used.snap = filt.snapshot()
    return used, filt


def _at_tag(est, event, v_mps):
    """(FilterState, s_m, sigma_s_m, d_m) of a placement at a tag read: pending a second reference unless the
    operator's declared position agrees."""
    tag_s_m, d_m, in_field, span_s = event.data   # the board's speed, no faster than the motor drives
    offset_m, var_m2 = tag_read_model(est.noise, min(abs(v_mps), est._wheel.top_mps) * span_s, in_field)
    s_m, sigma_s_m = tag_s_m - offset_m, sqrt(var_m2)
    bias_m = est.params.tag_bias_m
    fused = with_declared(est._declared, s_m, sigma_s_m, est.layout.loop_length_m, d_m)
    if fused is not None:   # a tag and the operator agree
        s_m, sigma_s_m = fused
        used = FilterState(None, tags_used=1)
    else:
        used = FilterState(None, tags_used=1, doubt=(-bias_m, bias_m), pending="tag")
    used.reach = est._reads.reach_around(s_m, 3.0 * sigma_s_m + bias_m, d_m)
    used.vouched = (d_m, s_m, 3.0 * sigma_s_m + bias_m) + (est._band0 or (None, None))   # vouched from here on
    return used, s_m, sigma_s_m, d_m


def _at_fixes(est, event, d_m):
    """(FilterState, s_m, sigma_s_m, d_m) of a placement where `locate_fixes` IPS fixes up to `event` agree; None
    while too few do."""
    anchors = []
    for e in est._events:
        if e.kind == "ips":
            anchors.append(est.layout.project(*e.data) - odometer_at(est._events, e.t_s)[0])
        if e is event:
            break
    placed = est._ips.agreeing(anchors[-(2 * est.params.locate_fixes - 1):])
    if placed is None:
        return None
    s_m, sigma_s_m = placed[0] + d_m, placed[1]
    # fixes of one IPS may share one lasting error (multipath): the placement covers it until a balise
    bias_m = est.params.ips_bias_m
    fused = with_declared(est._declared, s_m, sigma_s_m, est.layout.loop_length_m, d_m)
    if fused is not None:   # the IPS and the operator agree: both placements, fused
        s_m, sigma_s_m = fused
    low_m, high_m = (0.0, 0.0) if est._doubt_span is None else \
        span_offsets_m(est.layout, est._doubt_span, s_m)
    if fused is not None:
        used = FilterState(None, ips_used=est.params.locate_fixes,
                           doubt=None if est._doubt_span is None else (low_m, high_m))
    else:
        used = FilterState(None, ips_used=est.params.locate_fixes,
                           doubt=(min(low_m, -bias_m), max(high_m, bias_m)), pending="ips")
    used.reach = est._reads.reach_around(s_m, 3.0 * sigma_s_m + (0.0 if fused is not None else bias_m), d_m)
    used.ips_d_m = d_m   # placed by the fixes: the IPS watches the wheel from here
    if est._band0 is not None:   # the wheel's band, brought along by a train that turned
        used.vouched = (None, None, None) + tuple(est._band0)
    return used, s_m, sigma_s_m, d_m


def with_declared(declared, s_m, sigma_s_m, ring_m, d_m):
    """(s_m, sigma_s_m) of the placement at `s_m` (1-sigma `sigma_s_m`, odometer `d_m`) fused with `declared` (what an
    operator declared, carried to `d_m`: estimate.declared_at; its tolerance taken as 3 sigma) when the two agree
    within 3 sigma of both; None when they do not, or nothing was declared."""
    if declared is None:
        return None
    d_s_m, tol_m = declared_at(declared, d_m)
    d_sigma_m = max(tol_m / 3.0, 1e-4)
    off_m = circular_offset_m(d_s_m, s_m, ring_m)
    if abs(off_m) > 3.0 * hypot(sigma_s_m, d_sigma_m):
        return None
    w = sigma_s_m ** 2 / (sigma_s_m ** 2 + d_sigma_m ** 2)
    return s_m + w * off_m, sqrt((1.0 - w) * sigma_s_m ** 2)


def odometer_at(events, t_s):
    """(odometer m, speed m/s) at board time `t_s`, interpolated between the encoder reports among `events` around it;
    None when none is kept."""
    before = after = None
    for e in events:
        if e.kind != "odo":
            continue
        if e.t_s <= t_s:
            before = e
        else:
            after = e
            break
    if before is None:
        before = after
    if before is None:
        return None
    if after is None or after is before:
        d_m, v_mps = before.data
        return d_m + v_mps * (t_s - before.t_s), v_mps
    w = (t_s - before.t_s) / (after.t_s - before.t_s)
    d_m = before.data[0] + w * (after.data[0] - before.data[0])
    v_mps = (after.data[0] - before.data[0]) / (after.t_s - before.t_s)
    return d_m, v_mps
