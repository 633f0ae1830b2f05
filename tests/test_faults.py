"""Faults by name (cbtc.sim.faults): each parses with its parameters checked, and acts in the simulated world, never in
the controller; `cbtc sim --fault` runs them."""

import logging
from dataclasses import replace

import pytest

from cbtc.cli import main
from cbtc.errors import ConfigError
from cbtc.layout_files import load_layout
from cbtc.sim import fault_effects, faults
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import queue_scenario

AT_S = 8.0


@pytest.fixture(autouse=True)
def quiet():
    logging.disable(logging.WARNING)
    yield
    logging.disable(logging.NOTSET)


def run(text, until_s, encoder_channels=2):
    config = queue_scenario(load_layout("itb_square"), 2, seed=0, duration_s=until_s)
    config.faults = (faults.parse(text),)
    if encoder_channels != 2:
        config = replace(config, trains=[replace(t, profile=t.profile.with_changes(encoder_channels=encoder_channels))
                                         for t in config.trains])
    sim = Simulation(config)
    sim.scheduler.run_until(AT_S - 0.01)
    return sim, sim.trains[0], sim.zc.state_of("T1")


def test_every_fault_has_a_schedule_and_its_parameters_are_checked():
    assert set(faults.FAULTS) == set(fault_effects.SCHEDULE)
    assert str(faults.parse("link_loss:train=T2,loss=0.5")) == \
        "link_loss:at_s=20.0,burst_s=0.0,direction=both,duration_s=5.0,loss=0.5,train=T2"
    for text, says in (("nope", "unknown; known: boot_moved, broker_outage"),
                       ("stop_dead:speed=3", "PARAM=VALUE with PARAM"),
                       ("encoder_burst:counts=x", "a whole number"), ("reboot:at_s=nan", "finite"),
                       ("link_loss:loss=2", "share of messages"), ("rollback:v_mps=0", "rolling speed"),
                       ("rfid_misses:share=1", "probability in"), ("link_loss:direction=sideways", "direction"),
                       ("encoder_stuck:duration_s=-1", ">= 0")):
        with pytest.raises(ConfigError, match=says):
            faults.parse(text)


def test_stop_dead_stops_the_train_where_it_is():
    sim, train, _state = run(f"stop_dead:at_s={AT_S}", 11.0)
    assert train.v_mps > 0.1
    sim.scheduler.run_until(11.0)
    assert train.stopped_dead and train.v_mps == 0.0


def test_reboot_restarts_the_board_and_the_zone_locates_it_afresh():
    sim, train, state = run(f"reboot:at_s={AT_S}", 16.0)
    sim.scheduler.run_until(16.0)
    assert train.boots == 2 and state.restarts == 1 and state.boots.boot == train.obu.boot_id


def test_link_loss_silences_the_train_for_its_duration():
    sim, train, state = run(f"link_loss:at_s={AT_S},duration_s=2,direction=up", 12.0)
    sim.scheduler.run_until(AT_S + 1.9)
    assert AT_S + 1.9 - state.report_recv_s > 1.8        # nothing heard since the loss began
    sim.scheduler.run_until(12.0)
    assert 12.0 - state.report_recv_s < 0.2               # heard again after it


def test_encoder_burst_moves_the_odometer_and_not_the_train():
    sim, train, state = run(f"encoder_burst:at_s={AT_S},counts=300", 9.0)
    before_mm, true_m = train.obu.odo_mm, train.travelled_m
    sim.scheduler.run_until(AT_S + 0.05)
    moved_mm = (train.travelled_m - true_m) * 1000
    assert train.obu.odo_mm - before_mm > 300 + moved_mm - 5
    # caught where it shows first: the board's own check (faster than the motor drives) or the zone's jump check
    assert state.odometer_jumps >= 1 or (state.encoder_failures >= 1 and "enc_fail" in train.obu.faults)


def test_encoder_stuck_freezes_the_count_and_the_board_trips():
    sim, train, _state = run(f"encoder_stuck:at_s={AT_S},duration_s=3", 12.0)
    assert train.v_mps > 0.1
    sim.scheduler.run_until(AT_S + 1.0)
    assert train.obu.enc_fails >= 1 and train.encoder.count() == train.obu.odo_mm * train.profile.counts_per_m // 1000


def test_ips_offset_places_the_fixes_ahead():
    sim, train, _state = run(f"ips_offset:at_s={AT_S},duration_s=2,offset_m=0.5", 10.0)
    sim.scheduler.run_until(AT_S + 0.5)
    assert train.ips.offset_m == 0.5
    sim.scheduler.run_until(10.0)
    assert train.ips.offset_m == 0.0


def test_sim_takes_faults_and_names_a_bad_one_before_running(capsys):
    sim = ["sim", "--layout", "itb_square", "--trains", "2"]
    assert main(sim + ["--fault", "reboot:train=Q"]) == 2
    assert "no train 'Q' in this run; trains: T1, T2" in capsys.readouterr().err
    assert main(sim + ["--duration", "8", "--fault", "stop_dead:at_s=5", "--fault", "link_loss:train=T2,at_s=6",
                       "--json"]) in (0, 1)
    assert '"collisions"' in capsys.readouterr().out


def test_ips_blackout_and_rfid_absent_silence_those_sensors_for_a_while():
    sim, train, state = run(f"ips_blackout:at_s={AT_S},duration_s=2", 11.0)
    sim.scheduler.run_until(AT_S + 0.3)                   # fixes already in flight have landed
    used = state.estimator.counters()["ips_used"]
    sim.scheduler.run_until(AT_S + 1.9)
    assert train.ips.unplugged and state.estimator.counters()["ips_used"] == used
    sim.scheduler.run_until(11.0)
    assert not train.ips.unplugged and state.estimator.counters()["ips_used"] > used
    sim, train, _state = run(f"rfid_absent:at_s={AT_S},duration_s=2", 11.0)
    sim.scheduler.run_until(AT_S + 0.5)
    assert "rfid_absent" in train.obu.faults
    sim.scheduler.run_until(11.0)
    assert "rfid_absent" not in train.obu.faults


def test_encoder_scale_makes_the_odometer_read_long_for_a_while():
    sim, train, _state = run(f"encoder_scale:at_s={AT_S},duration_s=2,factor=1.5", 11.0)
    odo_mm, true_m = train.obu.odo_mm, train.travelled_m
    sim.scheduler.run_until(AT_S + 2.0)
    counted_mm, moved_mm = train.obu.odo_mm - odo_mm, (train.travelled_m - true_m) * 1000
    assert moved_mm > 50 and counted_mm > 1.3 * moved_mm
    sim.scheduler.run_until(11.0)
    assert train.encoder.scale_fault == 1.0


def test_link_delay_ages_the_trains_reports():
    sim, train, state = run(f"link_delay:at_s={AT_S},duration_s=3,latency_s=0.3,jitter_s=0,direction=up", 11.5)
    sim.scheduler.run_until(AT_S + 2.0)
    assert sim.scheduler.now_s() - state.report_t_s > 0.28     # the newest report the zone has is 0.3 s old
    sim.scheduler.run_until(11.5)
    assert sim.scheduler.now_s() - state.report_t_s < 0.2


def test_broker_outage_stops_every_train_and_operation_resumes():
    sim, train, _state = run(f"broker_outage:at_s={AT_S},duration_s=3", 25.0)
    sim.scheduler.run_until(AT_S + 2.9)
    assert not sim.broker.running and all(t.v_mps == 0.0 for t in sim.trains)
    before = [t.travelled_m for t in sim.trains]
    sim.scheduler.run_until(25.0)
    assert sim.broker.running and all(t.travelled_m > d + 0.5 for t, d in zip(sim.trains, before))


def test_ips_outliers_are_gated_and_rfid_misses_read_no_tag_for_a_while():
    sim, train, state = run(f"ips_outliers:at_s={AT_S},duration_s=4,share=0.6", 12.5)
    rejected = state.estimator.counters()["ips_rejected"]
    sim.scheduler.run_until(11.9)
    assert train.ips._profile.ips_outlier == 0.6 and state.estimator.counters()["ips_rejected"] > rejected + 3
    sim.scheduler.run_until(12.5)
    assert train.ips._profile is train.profile
    sim, train, state = run(f"rfid_misses:at_s={AT_S},duration_s=10,share=0.999", 18.0)
    used = state.estimator.counters()["tags_used"]
    sim.scheduler.run_until(17.9)
    assert train.travelled_m > 3.0 and state.estimator.counters()["tags_used"] == used   # a lap's tags, none read


def test_controller_restart_stops_the_trains_and_a_new_session_governs_them():
    sim, train, _state = run(f"controller_restart:at_s={AT_S},duration_s=3", 25.0)
    old_session = sim.zc.session_id
    sim.scheduler.run_until(AT_S + 2.9)
    assert all(t.v_mps == 0.0 for t in sim.trains)        # their commands expired: braked to a stop
    before = [t.travelled_m for t in sim.trains]
    sim.scheduler.run_until(25.0)
    assert sim.zone_restarts == 1 and sim.zc.session_id != old_session
    assert all(t.obu.sid == sim.zc.session_id for t in sim.trains)
    assert all(t.travelled_m > d + 0.5 for t, d in zip(sim.trains, before))
    assert sim.recorder.summary()["collisions"] == 0


def test_link_loss_in_bursts_cuts_the_link_in_whole_outages():
    sim, train, state = run(f"link_loss:at_s={AT_S},duration_s=6,loss=0.5,burst_s=0.5,direction=up", 15.0)
    heard = []
    sim.scheduler.call_every(0.05, lambda now_s: heard.append(now_s - state.report_recv_s), start_s=AT_S + 0.1)
    sim.scheduler.run_until(15.0)
    silences = [a for a in heard[:118] if a > 0.3]       # within the fault's window: silences of up to 0.5 s
    assert silences and max(heard[:118]) < 2.5 and max(heard[125:]) < 0.2


def test_link_reorder_and_duplicate_reach_the_zone_which_refuses_the_old_and_the_repeated():
    for text in ("link_reorder:share=0.5,delay_s=0.2", "link_duplicate:share=0.5"):
        sim, train, state = run(f"{text},at_s={AT_S},duration_s=3,direction=up", 11.5)
        refused = state.reports_rejected
        sim.scheduler.run_until(11.5)
        assert state.reports_rejected > refused + 5 and train.v_mps > 0.05, text
        assert sim.recorder.summary()["collisions"] == 0


def test_rfid_wrong_tag_reads_tags_that_are_elsewhere():
    sim, train, state = run(f"rfid_wrong_tag:at_s={AT_S},duration_s=10,share=0.99", 18.0)
    reads = []
    real_poll = train.rfid.poll

    def poll(now_ms):
        uid = real_poll(now_ms)
        if uid is not None:
            reads.append((uid, train.head_s))
        return uid
    train.rfid.poll = poll
    sim.scheduler.run_until(18.0)
    where = {tag.uid: tag.s_m for tag in sim.config.layout.tags}
    layout = sim.config.layout
    far = [uid for uid, s_m in reads if min(layout.ahead_m(where[uid], s_m), layout.ahead_m(s_m, where[uid])) > 0.2]
    assert len(reads) >= 3 and len(far) >= len(reads) - 1


def test_rollback_rolls_the_standing_train_back_and_its_encoder_counts_on():
    """It rolls only while standing undriven: a drive forward holds it; a one-channel encoder counts it up."""
    sim, train, _state = run(f"rollback:at_s={AT_S},distance_m=0.2,v_mps=0.1", 9.0, encoder_channels=1)
    sim.scheduler.run_until(AT_S + 0.01)
    while not train.rolling_back:                         # it waits for the train to stand (at a station)
        sim.scheduler.run_until(sim.scheduler.now_s() + 0.05)
        assert sim.scheduler.now_s() < 40.0
    true_m, count, left_m = train.travelled_m, train.encoder.count(), train.rollback_left_m
    while train.rolling_back:                             # until it has rolled it all, or is driven again
        sim.scheduler.run_until(sim.scheduler.now_s() + 0.02)
    rolled_m = left_m - train.rollback_left_m
    # a roll back from a stand a mm short of the station: it rolls until the board drives it up to the mark again
    assert rolled_m > 0.01 and train.travelled_m == pytest.approx(true_m - rolled_m, abs=0.01)
    assert train.encoder.count() - count >= 0.95 * rolled_m * train.profile.counts_per_m


def test_the_fault_table_of_the_docs_lists_every_fault_with_its_parameters_and_campaign_ranges():
    import pathlib

    from cbtc.experiments import campaign
    doc = (pathlib.Path(__file__).parent.parent / "docs" / "faults.md").read_text()
    rows = {line.split("|")[1].strip(" `"): line for line in doc.splitlines() if line.startswith("| `")}
    assert set(faults.FAULTS) <= set(rows) and set(campaign.CAMPAIGN_RANGES) == set(faults.FAULTS)
    for name, (what, params) in faults.FAULTS.items():
        assert what in rows[name], name
        assert all(f"`{k}={v}`" in rows[name] for k, v in params.items()), name
        assert all(f"`{k}`" in rows[name] for k in campaign.CAMPAIGN_RANGES[name]), name
