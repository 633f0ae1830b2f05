"""A train that starts just past a station is not an overrun: it passes it by this time round and stops there on
its next lap, with nothing said."""

import logging

from cbtc.scenario_files import load_scenario
from cbtc.sim.simulation import Simulation

SCENARIO = """\
name: past_a_station
layout: lego_oval
duration_s: 20
trains:
  - {id: A, start: 1.2}
  - {id: B, start: 3.5, stops: [north]}
"""


def test_a_train_starting_past_its_only_station_stops_there_next_lap_with_no_warning(tmp_path, caplog):
    path = tmp_path / "past.yaml"
    path.write_text(SCENARIO)
    sim = Simulation(load_scenario(str(path)))
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        sim.run()
    view = sim.zc.view(sim.scheduler.now_s()).train("B")
    assert view.stop_overruns == 0 and view.station_stops == 1, view
    assert not [r for r in caplog.records if "overran" in r.getMessage()]
