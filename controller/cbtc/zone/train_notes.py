"""What a train's reports say of its board that the zone tells the user: reports that do not answer its commands,
a roll-away hold, a reverse-movement trip, a train line come open, an estimated gap its ranging disagrees with."""

import logging

log = logging.getLogger("cbtc.zone")
DEAF_WARN_S = 2.0   # a train whose reports do not answer our commands for this long is named in a warning


def watch_answers(state, recv_s):
    """Warn once when a train's reports have not answered our commands for DEAF_WARN_S: the zone holds every
    train meanwhile, and the user needs to know which board and why."""
    if state.boots.answered or state.answered_s is None:
        state.deaf_since_s = None
    elif state.deaf_since_s is None:
        state.deaf_since_s = recv_s
    elif recv_s - state.deaf_since_s >= DEAF_WARN_S:
        log.warning("train %s: its reports have not answered this controller's commands for %.0f s, so no train "
                    "gets authority; check that its board has the same key as the controller and that no other "
                    "controller commands it (or its reports are replayed)", state.train_id,
                    recv_s - state.deaf_since_s)
        state.deaf_since_s = float("inf")   # said once, until it answers again


def note_motion_faults(state, report, previous, recv_s, refusals, watch):
    """Log, once each time it begins, a board's roll-away hold and its reverse-movement trip; a train line come open
    leaves its car's place an obstacle (ObstacleWatch.car_come_off)."""
    before = () if previous is None else previous["flt"]
    if "hold" in report["flt"] and "hold" not in before:
        refusals.note(state.train_id, "rolled back", "standing undriven, it rolled back over 2 cm (a slope "
                      "its brake does not hold?): its board drives it back to where it stood", recv_s)
    if "reverse" in report["flt"] and "reverse" not in before:
        refusals.note(state.train_id, "ran backwards", "driven forward, it ran backwards over 2 cm: its "
                      "board brakes it for good; check the motor's wires, then reboot the board", recv_s)
    if "split" in report["flt"] and state.train_id not in watch.parted:
        watch.car_come_off(state, "split" not in before, recv_s)


def note_gap(state, alarm, gap_est_m, use_measured_gap):
    """Keep `state`'s "picture disagrees" alarm (`alarm`: None when no measured gap was set against the estimated
    one), said once each time it is raised."""
    if alarm is None:
        state.gap_alarm = False
        return
    if alarm and not state.gap_alarm:
        state.gap_alarms += 1
        log.warning("train %s: picture disagrees: estimated gap %.3f m, measured %.3f m by its ranging; %s",
                    state.train_id, gap_est_m, state.rng_gap[1],
                    "the authority takes the shorter; check the two trains' IPS and wheels" if use_measured_gap
                    else "the authority rests on the estimate alone; the board's guard brakes on the measurement")
    state.gap_alarm = alarm
