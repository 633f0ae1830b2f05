"""Whether a train's report is one its physics allows, against the train's previous accepted report of the same boot.

Pure: reports and receive times in, a verdict out. The wire has already bounded every integer; these are the limits
of time and motion. A board's clock cannot run backwards, nor faster than the controller's by more than the slack,
and its report sequence advances no faster than one report per MIN_REPORT_MS of it;
its odometer cannot move faster than twice the motor's unloaded speed (a jump means the odometer is no longer
the train's: the controller locates the train afresh); a fix, tag or range stamped after its report or more than
STAMP_WINDOW_MS before it is not a measurement of this report, and is dropped.
"""

from cbtc.protocol import wire

wrap_diff = wire.wrap_diff   # named once: a module's attribute is looked up at every use

CLOCK_SLACK_S = 0.5      # board time may run ahead of receive time by this, plus CLOCK_RATE of it (transit jitter)
CLOCK_RATE = 0.02
SPEED_FACTOR = 2.0       # no train runs twice its motor's unloaded speed
ODO_SLACK_MM = 50        # odometer travel allowed beyond that (a count's quantisation, a stop's creep)
STAMP_WINDOW_MS = 2000   # a fix, tag or range stamped this long before its report is too old to be of it
MIN_REPORT_MS = 5        # a board reports at most once a loop pass: the sequence advances no faster than this
SEQ_SLACK = 10


def time_refusal(report: dict, previous: dict, recv_s: float, previous_recv_s: float) -> str:
    """Why `report`'s board time cannot follow `previous`'s (the same boot, received at `previous_recv_s`), or ""."""
    ahead_ms = wrap_diff(report["t_ms"], previous["t_ms"])
    if ahead_ms < 0:
        return f"board time ran back {-ahead_ms} ms from the previous report"
    silence_s = max(0.0, recv_s - previous_recv_s)
    if ahead_ms / 1000.0 > silence_s * (1.0 + CLOCK_RATE) + CLOCK_SLACK_S:
        return (f"board time ran {ahead_ms / 1000.0:.1f} s ahead in {silence_s:.1f} s of the controller's "
                f"(a board clock runs no faster)")
    skipped = wrap_diff(report["seq"], previous["seq"])
    if skipped > ahead_ms // MIN_REPORT_MS + SEQ_SLACK:
        return f"report seq {report['seq']} skips {skipped} reports in {ahead_ms} ms of board time"
    return ""


def odometer_jump_mm(report: dict, previous: dict, v_noload_mps: float) -> int:
    """How far (mm) `report`'s odometer moved beyond what the train could travel since `previous`; 0 if it could."""
    dt_s = max(0, wrap_diff(report["t_ms"], previous["t_ms"])) / 1000.0
    reach_mm = SPEED_FACTOR * v_noload_mps * 1000.0 * dt_s + ODO_SLACK_MM
    return max(0, int(abs(report["odo_mm"] - previous["odo_mm"]) - reach_mm))


def _stamped_ok(t_ms: int, report_t_ms: int) -> bool:
    return 0 <= wrap_diff(report_t_ms, t_ms) <= STAMP_WINDOW_MS


def plausible_parts(report: dict, previous_odo_mm) -> tuple:
    """(`report` with its IPS fix, tags and range kept only where their stamps are of it, how many were dropped).
    A tag's odometer must also lie between `previous_odo_mm` (None: unknown) and the report's, with the slack."""
    t_ms = report["t_ms"]
    dropped = 0
    ips = report["ips"]
    if ips is not None and not _stamped_ok(ips[0], t_ms):
        ips, dropped = None, dropped + 1
    tags = []
    low_mm = report["odo_mm"] if previous_odo_mm is None else min(previous_odo_mm, report["odo_mm"])
    high_mm = report["odo_mm"] if previous_odo_mm is None else max(previous_odo_mm, report["odo_mm"])
    for tag in report["tags"]:
        in_reach = low_mm - ODO_SLACK_MM <= tag[1] <= high_mm + ODO_SLACK_MM
        if _stamped_ok(tag[2], t_ms) and (previous_odo_mm is None or in_reach):
            tags.append(tag)
        else:
            dropped += 1
    rng = report.get("rng")
    if rng is not None and not _stamped_ok(rng[0], t_ms):
        rng, dropped = None, dropped + 1
    if not dropped:
        return report, 0
    return dict(report, ips=ips, tags=tags, rng=rng), dropped
