"""What the zone sends: every command a train gets says something new (a command the board already holds, same
report and same fields, is not sent again), and every report taken is answered."""

from cbtc.layout_files import load_layout
from cbtc.protocol import wire
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import paper_scenario, train_key


def test_no_command_repeats_the_one_before_and_every_report_is_answered():
    config = paper_scenario(load_layout("itb_square"), seed=2, laps=None, duration_s=30.0)
    sim = Simulation(config)
    sent = {spec.train_id: [] for spec in config.trains}
    publish = sim.zc_client.publish

    def capture(topic, payload, *args, **kwargs):
        if topic.endswith("/cmd"):
            train_id = wire.train_id_of(topic)
            sent[train_id].append(wire.decode_command(train_key(config.seed, train_id), topic, payload))
        return publish(topic, payload, *args, **kwargs)

    sim.zc_client.publish = capture
    summary = sim.run().summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    for train_id, commands in sent.items():
        assert len(commands) > 500, train_id
        for before, after in zip(commands, commands[1:]):
            assert after["seq"] == before["seq"] + 1
            assert {k: v for k, v in after.items() if k != "seq"} != {k: v for k, v in before.items() if k != "seq"}
        # each report the zone took (after the train was located) has its own answer
        answered = {c["rseq"] for c in commands}
        taken = sim.zc.state_of(train_id).reports_taken
        assert len(answered) >= taken - 20, (train_id, len(answered), taken)
    for row in summary["trains"]:
        assert row["commands_rejected_onboard"] == 0, row
