"""How each fault of cbtc.sim.faults acts on the simulated world: `inject` schedules each on the simulation's clock,
one function a fault (`SCHEDULE`: name -> function(sim, train, params)). Drivers, links, boards and the broker are
changed; the controller never is."""

import random
import zlib
from dataclasses import replace

from cbtc.errors import ConfigError
from cbtc.sim.faults import PATH_ONLY, SWITCH_FAULTS, Fault


def inject(sim, faults) -> None:
    """Schedule every fault of `faults` (Fault values) on `sim`'s clock; ConfigError for a train it does not have."""
    trains = {t.train_id: t for t in sim.trains}
    layout = sim.config.layout
    for fault in faults:
        if sim.network and fault.name in PATH_ONLY:
            raise ConfigError(f"fault {fault.name} places or measures things along a single path: not on the track "
                              f"network {layout.name} yet; run it on a loop or a line, or pick another fault")
        if not sim.network and fault.name in SWITCH_FAULTS:
            raise ConfigError(f"fault {fault.name} needs a track network with switches; layout {layout.name} has "
                              f"none: run it on lego_passing_loop or lego_figure_eight")
        train = None
        if "train" in fault.params:
            train = trains.get(fault.params["train"] or sim.trains[0].train_id)
        if "train" in fault.params and train is None:
            raise ConfigError(f"fault {fault}: no train {fault.params['train']!r} in this run; trains: "
                              f"{', '.join(sorted(trains))}")
        SCHEDULE[fault.name](sim, train, fault.params)


def _stop_dead(sim, train, p):
    sim.scheduler.call_at(p["at_s"], train.stop_dead)


def _reboot(sim, train, p):
    sim.scheduler.call_at(p["at_s"], lambda: train.reboot(sim.scheduler.now_s()))


def _link_for_a_while(sim, train, p, profile):
    """The train's link in p["direction"] follows `profile` from at_s for duration_s, then the run's own again."""
    client_id = f"train-{train.train_id}"
    up = profile if p["direction"] in ("up", "both") else None
    down = profile if p["direction"] in ("down", "both") else None
    sim.scheduler.call_at(p["at_s"], sim.broker.set_link, client_id, up, down)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], sim.broker.set_link, client_id,
                          sim.config.link if up else None, sim.config.link if down else None)


def _link_loss(sim, train, p):
    if p["burst_s"] <= 0.0 or p["loss"] in (0.0, 1.0):
        _link_for_a_while(sim, train, p, replace(sim.config.link, loss=p["loss"]))
        return
    # outages of burst_s with exponential gaps whose mean makes `loss` the share of time lost: drawn from the run's
    # seed and the fault, so the same run loses the same bursts
    rng = random.Random(zlib.crc32(f"{sim.config.seed}/{Fault('link_loss', p)}".encode()))
    mean_gap_s = p["burst_s"] * (1.0 - p["loss"]) / p["loss"]
    t_s, end_s = p["at_s"] + rng.expovariate(1.0 / mean_gap_s), p["at_s"] + p["duration_s"]
    while t_s < end_s:
        burst_s = min(p["burst_s"], end_s - t_s)
        _link_for_a_while(sim, train, dict(p, at_s=t_s, duration_s=burst_s), replace(sim.config.link, loss=1.0))
        t_s += burst_s + rng.expovariate(1.0 / mean_gap_s)


def _link_reorder(sim, train, p):
    _link_for_a_while(sim, train, p, replace(sim.config.link, reorder=p["share"], reorder_s=p["delay_s"]))


def _link_duplicate(sim, train, p):
    _link_for_a_while(sim, train, p, replace(sim.config.link, duplicate=p["share"]))


def _rfid_wrong_tag(sim, train, p):
    _for_a_while(sim, p, train.rfid, "wrong_tag", p["share"])


def _rollback(sim, train, p):
    sim.scheduler.call_at(p["at_s"], train.roll_back, p["distance_m"], p["v_mps"])


def _length_wrong(sim, train, p):
    layout = sim.config.layout
    others = [t for t in sim.trains if t is not train]
    room = [layout.ahead_m(t.head_s, train.tail_s) for t in others] if layout.closed else \
        [train.tail_s - t.head_s for t in others if t.head_s <= train.tail_s] + [train.tail_s]
    train.length_m = max(0.05, min([p["length_m"]] + [train.length_m + r - 0.15 for r in room]))


def _car_dropped(sim, train, p):
    def drop():
        car_m = min(p["length_m"], train.length_m - 0.1)
        if car_m < 0.01:
            return
        car_head_s = sim.config.layout.wrap(train.tail_s + car_m)
        train.length_m -= car_m
        car = sim.add_stray("C" + train.train_id, train._key, car_head_s, train.profile.with_changes(length_m=car_m))
        car.frozen = car.stopped_dead = True   # a car has no board: it neither moves nor reports
        train.tail_car = car
        if train.train_line is not None:
            train.train_line.open = True   # the train line parts with the coupling
    sim.scheduler.call_at(p["at_s"], drop)


def _reverse_run(sim, train, p):
    sim.scheduler.call_at(p["at_s"], train.run_reversed, p["distance_m"])


def _encoder_burst(sim, train, p):
    _jump_encoder(sim, train, p["at_s"], p["counts"] / train.profile.counts_per_m)


def _odometer_jump(sim, train, p):
    _jump_encoder(sim, train, p["at_s"], p["distance_m"])


def _jump_encoder(sim, train, at_s, distance_m):
    """At `at_s` the train's encoder count jumps by `distance_m` (either way): spurious edges are edges, the newest
    of them is now."""
    def jump():
        train.encoder.distance_m += distance_m
        train.encoder._since_edge_s = 0.0
    sim.scheduler.call_at(at_s, jump)


def _encoder_stuck(sim, train, p):
    encoder = train.encoder
    real_count = encoder.count

    def stick():
        frozen = real_count()
        encoder.count = lambda: frozen

    def release():
        encoder.count = real_count
    sim.scheduler.call_at(p["at_s"], stick)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], release)


def _ips_offset(sim, train, p):
    def shift(offset_m):
        train.ips.offset_m = offset_m
    sim.scheduler.call_at(p["at_s"], shift, p["offset_m"])
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], shift, 0.0)


def _for_a_while(sim, p, obj, name, value):
    """`obj.name` = `value` from at_s for duration_s, then as it was."""
    def set_to(v):
        setattr(obj, name, v)
    sim.scheduler.call_at(p["at_s"], set_to, value)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], set_to, getattr(obj, name))


def _ips_blackout(sim, train, p):
    _for_a_while(sim, p, train.ips, "unplugged", True)


def _rfid_absent(sim, train, p):
    _for_a_while(sim, p, train.rfid, "present", False)


def _encoder_scale(sim, train, p):
    _for_a_while(sim, p, train.encoder, "scale_fault", p["factor"])


def _link_delay(sim, train, p):
    _link_for_a_while(sim, train, p, replace(sim.config.link, latency_s=p["latency_s"], jitter_s=p["jitter_s"]))


def _broker_outage(sim, _train, p):
    def back():
        sim.broker.start()
        for client in sim.clients():
            client.reconnect()
        sim.zc.start()
    sim.scheduler.call_at(p["at_s"], sim.broker.stop)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], back)


def _ips_outliers(sim, train, p):
    _for_a_while(sim, p, train.ips, "_profile", train.profile.with_changes(ips_outlier=p["share"]))


def _rfid_misses(sim, train, p):
    _for_a_while(sim, p, train.rfid, "_profile", train.profile.with_changes(rfid_miss=p["share"]))


def _controller_restart(sim, _train, p):
    sim.scheduler.call_at(p["at_s"], sim.crash_zone)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], sim.restart_zone)


def _ips_bias(sim, train, p):
    _ips_offset(sim, train, p)
    _rfid_misses(sim, train, p)


def _encoder_drift(sim, train, p):
    _encoder_scale(sim, train, p)
    _ips_blackout(sim, train, p)


def _boot_moved(sim, train, p):
    def reboot_and_carry():
        train.reboot(sim.scheduler.now_s())
        train.carry(_room_m(sim, train, p["distance_m"]))
    sim.scheduler.call_at(p["at_s"], reboot_and_carry)


def _room_m(sim, train, distance_m):
    """`distance_m` cut to the room the trains either side leave, 10 cm clear of their tails ahead and of the track a
    train behind may still run on (its head, or the end of the authority the zone gave it): a user puts a train
    down on free track, not into another's way."""
    layout = sim.config.layout
    others = [t for t in sim.trains if t is not train]
    if distance_m >= 0.0:
        room = [layout.ahead_m(train.head_s, t.tail_s) for t in others] if layout.closed else \
            [t.tail_s - train.head_s for t in others if t.tail_s >= train.head_s] + [layout.length_m - train.head_s]
    else:
        fronts = [_front_s(sim, t) for t in others]
        # a front already past the tail (an authority reaching into the train) leaves no room, not a loop's worth
        room = [_short_ahead_m(layout, front, train.tail_s) for front in fronts] if layout.closed else \
            [train.tail_s - front for front in fronts if front <= train.tail_s] + [train.tail_s]
    room_m = max(0.0, min(room + [abs(distance_m) + 0.1]) - 0.1)
    return room_m if distance_m >= 0.0 else -room_m


def _short_ahead_m(layout, from_s, to_s):
    """How far `to_s` lies ahead of `from_s` on a loop, 0 when it lies behind it (the short way round)."""
    ahead_m = layout.ahead_m(from_s, to_s)
    return ahead_m if ahead_m <= layout.length_m / 2 else 0.0


def _front_s(sim, train):
    """The front of the track `train` may run on: the end of the authority its board holds (at a wheel reading 10 %
    short, and the margin beyond) or the zone set, or its head."""
    layout = sim.config.layout
    reach_m = 0.0
    state = sim.zc.trains.get(train.train_id)
    if state is not None and state.limit_s is not None:
        ahead_m = layout.ahead_m(train.head_s, state.limit_s)
        reach_m = ahead_m if ahead_m < layout.length_m / 2 else 0.0
    obu = train.obu
    if obu.command_valid(train.board_ms(sim.scheduler.now_s())):
        reach_m = max(reach_m, (obu.eoa_mm - obu.odo_mm) / 1000.0 / 0.9 + sim.config.params.margin_m)
    return layout.wrap(train.head_s + reach_m)


def _unknown_board(sim, train, p):
    from cbtc.zone.config import train_key
    sim.scheduler.call_at(p["at_s"], _put_stray, sim, train, p["distance_m"], "X" + train.train_id,
                          train_key(sim.config.seed + 1, "X" + train.train_id))


def _duplicate_board(sim, train, p):
    sim.scheduler.call_at(p["at_s"], _put_stray, sim, train, p["distance_m"], train.train_id, train._key)


def _unseen_train(sim, train, p):
    from cbtc.zone.config import train_key

    def put():
        stray = _put_stray(sim, train, p["distance_m"], "U" + train.train_id,
                           train_key(sim.config.seed + 2, "U" + train.train_id))
        if stray is not None:
            stray.frozen = stray.stopped_dead = True   # no working board: it neither moves nor reports
    sim.scheduler.call_at(p["at_s"], sim.crash_zone)
    sim.scheduler.call_at(p["at_s"] + 0.5 * p["duration_s"], put)
    sim.scheduler.call_at(p["at_s"] + p["duration_s"], sim.restart_zone)


def _put_stray(sim, train, distance_m, train_id, key):
    """A standing board `distance_m` ahead of `train`'s head, where it fits clear of every train (0.2 m from their
    tails and from the end of authority of the one behind); in the largest free stretch when it does not; nowhere
    (None) when no stretch has room."""
    layout = sim.config.layout
    profile = train.profile
    clear_m = 0.2
    need_m = profile.length_m + 2 * clear_m
    stretches = []   # (start_s, length_m): from the front of a train's way to the tail of the train ahead of it
    everyone = sim.trains + sim.strays
    for t in everyone:
        front_s = _front_s(sim, t)
        if layout.closed:   # measured from its head: a tail between the head and the front leaves no stretch
            front_m = layout.ahead_m(t.head_s, front_s)
            ahead_m = [layout.ahead_m(t.head_s, o.tail_s) - front_m for o in everyone if o is not t]
        else:
            ahead_m = [o.tail_s - front_s for o in everyone if o is not t and o.tail_s >= t.head_s] + \
                [layout.length_m - front_s]
        stretches.append((front_s, max(0.0, min(ahead_m)) if ahead_m else layout.length_m - profile.length_m))
    wanted_s = layout.wrap(train.head_s + distance_m)
    for start_s, length_m in stretches:
        into_m = layout.ahead_m(start_s, wanted_s)
        if length_m >= need_m and profile.length_m + clear_m <= into_m <= length_m - clear_m:
            return sim.add_stray(train_id, key, wanted_s, profile)
    start_s, length_m = max(stretches, key=lambda st: st[1])
    if length_m >= need_m:
        return sim.add_stray(train_id, key, layout.wrap(start_s + 0.5 * (length_m + profile.length_m)), profile)
    return None


def _tag_moved(sim, train, p):
    def move():
        layout = sim.config.layout
        ahead = min(layout.tags, key=lambda tag: layout.ahead_m(train.head_s, tag.s_m) if layout.closed
                    else (tag.s_m - train.head_s if tag.s_m >= train.head_s else float("inf")))
        for t in sim.trains:
            t.rfid.move_tag(ahead.uid, p["distance_m"])
    sim.scheduler.call_at(p["at_s"], move)


def _switch_fault(name):
    def schedule(sim, _train, p):
        if not sim.switches:
            raise ConfigError(f"fault {name}: {sim.config.layout.name} has no switch; run it on a layout with "
                              "switches, such as lego_passing_loop (cbtc layout list)")
        switch = p["switch"] or next(iter(sim.switches))
        machine = sim.switches.get(switch)
        if machine is None:
            raise ConfigError(f"fault {name}: no switch {switch!r} on {sim.config.layout.name}; its switches: "
                              f"{', '.join(sim.switches)}")
        machine.fault, machine.fault_at_s, machine.fault_until_s = name, p["at_s"], p["at_s"] + p["duration_s"]
    return schedule


SCHEDULE = {"controller_restart": _controller_restart,
             "ips_bias": _ips_bias, "encoder_drift": _encoder_drift, "boot_moved": _boot_moved,
             "tag_moved": _tag_moved, "unknown_board": _unknown_board, "duplicate_board": _duplicate_board,
             "unseen_train": _unseen_train,
             "stop_dead": _stop_dead, "reboot": _reboot, "link_loss": _link_loss, "link_delay": _link_delay,
             "broker_outage": _broker_outage, "encoder_burst": _encoder_burst,
             "odometer_jump": _odometer_jump, "encoder_stuck": _encoder_stuck,
             "encoder_scale": _encoder_scale, "ips_offset": _ips_offset, "ips_blackout": _ips_blackout,
             "ips_outliers": _ips_outliers, "rfid_absent": _rfid_absent, "rfid_misses": _rfid_misses,
             "link_reorder": _link_reorder, "link_duplicate": _link_duplicate, "rfid_wrong_tag": _rfid_wrong_tag,
             "rollback": _rollback, "reverse_run": _reverse_run, "length_wrong": _length_wrong,
             "car_dropped": _car_dropped, **{name: _switch_fault(name) for name in SWITCH_FAULTS}}
