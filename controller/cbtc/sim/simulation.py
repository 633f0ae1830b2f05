"""A simulated run: virtual trains and a zone controller on the mock broker under a virtual clock.

`Simulation(config).run()` is reproducible from `config.seed`: same seed, same figures. It returns the run's
`Recorder` (sim/recorder.py), which turns truth, reports and authority limits into laps, gaps, collisions and
authority overruns.
"""

import numpy as np

from cbtc import run_clock
from cbtc.bus.mock_broker import MockBroker
from cbtc.errors import ConfigError
from cbtc.protocol import fast_wire, wire, wire_zc
from cbtc.scheduler import VirtualScheduler
from cbtc.sim import fault_effects, progress
from cbtc.sim.recorder import Recorder
from cbtc.sim.switch_machines import SwitchMachine
from cbtc.sim.tail_beacons import TailBeacons
from cbtc.sim.virtual_train import VirtualTrain
from cbtc.zone.config import ScenarioConfig, train_key
from cbtc.zone.factory import build_zone
from cbtc.zone.swept import SweptTrack

FIRST_CYCLE_S = 0.05   # the zone's first cycle: once the boards have had a loop or two to report
DECLARED_TOL_M = 0.02  # how close to its declared start an operator puts a train's head: on a mark (declare_start)


class Simulation:
    """Everything of one run, wired and ready to `run()`; the parts are public for tests and fault injection."""

    def __init__(self, config: ScenarioConfig, keep_reports: bool = False, keep_samples: bool = False):
        self.config = config
        fast_wire.remember_sealed()   # the boards and the zone here seal and read the same messages: hashed once
        layout = config.layout
        ids = [t.train_id for t in config.trains]
        if len(set(ids)) != len(ids):
            raise ConfigError(f"scenario: duplicate train ids in {ids}")
        if not config.trains:
            raise ConfigError("scenario: at least one train is needed")
        self.scheduler = VirtualScheduler()
        self.broker = MockBroker(self.scheduler, seed=config.seed)
        self.zc_client = self.broker.connect("zone-controller",
                                             will=(wire_zc.topic_zone_status("zc1"), b"offline", True),
                                             up=config.controller_up, down=config.controller_down)
        keys = {spec.train_id: train_key(config.seed, spec.train_id) for spec in config.trains}
        self.zc = build_zone(config, keys, self.zc_client, self.scheduler.now_s)
        self.policy = self.zc.policy
        self.trains = []
        self.strays = []   # boards on the track the zone was not configured for (faults unknown_board, duplicate_board)
        for index, spec in enumerate(config.trains):
            rng = np.random.default_rng([config.seed, index])
            client = self.broker.connect(f"train-{spec.train_id}",
                                         will=(wire.topic_status(spec.train_id), b"offline", True),
                                         up=config.link, down=config.link)
            offset_ms = int(rng.integers(0, 10_000_000))
            train = VirtualTrain(spec.train_id, train_key(config.seed, spec.train_id), spec.frame or layout,
                                 spec.profile, spec.s0_m, client, rng, offset_ms, obu_overrides=config.obu_overrides,
                                 ranging=self._ranging(index))
            train.route = spec.route   # on a network: the itinerary it runs (its frame's Route)
            if spec.legs:              # on a line: the legs it reverses between, its sensors on the first's
                train.legs = spec.legs
                train.ips.use_layout(spec.legs[0].sensors)
                train.rfid.use_layout(spec.legs[0].sensors)
            self.trains.append(train)
        if config.declare_start:
            for spec in config.trains:   # from truth, as an operator would at the start of a run (declare_start)
                self.zc.declare_position(spec.train_id, (spec.frame or layout).wrap(spec.s0_m), DECLARED_TOL_M)
        self.network = getattr(layout, "is_network", False)
        self.switches = {}   # on a network: switch id -> its SwitchMachine, which the zone commands and reads
        self.recorder = self._world(keep_reports, keep_samples)
        self._clear_track()
        self.zc.start()
        for train in self.trains:
            train.client.publish(wire.topic_status(train.train_id), b"online", retain=True)
        for index, train in enumerate(self.trains):
            # stagger the boards' loops a little, as real boards are
            self.scheduler.call_every(config.loop_s, self._ticker(train), start_s=0.001 * (index + 1))
        self._cycle = self.scheduler.call_every(config.cycle_s, self.zc.cycle, start_s=FIRST_CYCLE_S)
        self._keys = keys
        self.zone_restarts = 0
        self._report_sinks = []   # callables(train_id, report, recv_s): every report the zone accepts (a recording)
        self.scheduler.call_every(config.loop_s, self.recorder.sample, start_s=0.0105)
        self.tail_beacons = TailBeacons(self)
        if self.tail_beacons:
            self.scheduler.call_every(config.loop_s, self.tail_beacons.tick, start_s=0.0107)
        fault_effects.inject(self, config.faults)

    def _world(self, keep_reports, keep_samples):
        """The run's recorder; on a network, its switch machines first, wired to the zone and moving each loop."""
        config = self.config
        if self.network:
            from cbtc.sim.network_recorder import NetworkRecorder
            self.switches = {w: SwitchMachine(w) for w in config.layout.graph.switches}
            self._wire_switches()
            self.scheduler.call_every(config.loop_s, self._step_switches, start_s=0.0103)
            return NetworkRecorder(self)
        stuck = self.policy.stuck(config.layout, [(t.train_id, t.head_s, t.tail_s) for t in self.trains])
        if stuck is not None:
            raise ConfigError(stuck)
        return Recorder(self, keep_reports, keep_samples)

    def _wire_switches(self):
        """The zone reads the machines' detection and commands their moves (a lineside board's part on a table)."""
        machines = self.switches
        self.zc.network.detection = lambda now_s: {w: m.detected(now_s) for w, m in machines.items()}
        self.zc.network.on_move = lambda switch, leg, now_s: machines[switch].command(leg, now_s)

    def _step_switches(self, now_s):
        for machine in self.switches.values():
            machine.step(now_s)

    def add_stray(self, train_id, key, s0_m, profile):
        """A board put on the track at `s0_m` standing, reporting as `train_id` with `key`, which the zone was not
        configured for (or a second one under a configured id): truth counts it like any train, the zone sees only
        its reports."""
        from cbtc.sim.virtual_train import VirtualTrain
        index = len(self.trains) + len(self.strays)
        rng = np.random.default_rng([self.config.seed, index, 11])
        client = self.broker.connect(f"stray-{len(self.strays)}-{train_id}", up=self.config.link,
                                     down=self.config.link)
        stray = VirtualTrain(train_id, key, self.config.layout, profile, s0_m, client, rng,
                             int(rng.integers(0, 10_000_000)), obu_overrides=self.config.obu_overrides)
        stray.boots = 1 << 16 + len(self.strays)   # its own boot ids, as another board draws them
        stray.obu = stray._boot()
        self.strays.append(stray)
        self.scheduler.call_every(self.config.loop_s, self._ticker(stray), start_s=self.scheduler.now_s() + 0.0005)
        return stray

    def crash_zone(self):
        """The zone controller's process dies: its connection is cut (its will says offline), no cycle runs."""
        self.broker.kill_client("zone-controller")
        self._cycle.cancel()

    def restart_zone(self, hand_over: bool = False):
        """A new zone controller process: a new session, knowing nothing of the trains until they report; or, with
        `hand_over`, taking each train over from the old zone's record of it (cbtc.zone.handover)."""
        self.zone_restarts += 1
        self._cycle.cancel()
        now_s = self.scheduler.now_s()
        records = [self.zc.export_train(t.train_id, now_s) for t in self.trains] if hand_over else []
        self.zc_client.reconnect()
        self.zc = build_zone(self.config, self._keys, self.zc_client, self.scheduler.now_s,
                             seed=self.config.seed + 1000 * self.zone_restarts)
        for record in records:
            self.zc.import_train(record, now_s)
        self.policy = self.zc.policy
        if self.network:
            self._wire_switches()
        for sink in self._report_sinks:
            self.zc.reports.subscribe(sink)
        self._clear_track()
        self.zc.start()
        self._cycle = self.scheduler.call_every(self.config.cycle_s, self.zc.cycle)

    def _clear_track(self):
        """As an operator who has looked at the table (ScenarioConfig.clear_track "truth"): the zone is told that the
        track is clear but where a vehicle that is none of its trains stands (a stray board, a car come off)."""
        if self.config.clear_track != "truth":
            return
        layout = self.config.layout
        if not self.strays or self.network:   # a network: its strays are obstacles placed nowhere (all held)
            self.zc.clear_track(None, by="the simulation, from its truth,")
            return
        occupied = SweptTrack(layout)   # the union of the strays' extents
        for stray in self.strays:
            tail_s = stray.tail_s
            occupied.clear(tail_s, tail_s + layout.ahead_m(tail_s, stray.head_s) if layout.closed else stray.head_s)
        spans = occupied.spans
        clear = [(spans[i][1], spans[i + 1][0]) for i in range(len(spans) - 1)]
        if layout.closed:
            clear.append((spans[-1][1], spans[0][0]))
        else:
            clear = [(0.0, spans[0][0])] + clear + [(spans[-1][1], layout.length_m)]
        self.zc.clear_track([(a, b) for a, b in clear if a != b], by="the simulation, from its truth,")

    def wrap_zone(self, wrap):
        """Run the zone's report handling and cycles through `wrap(fn)` (cbtc bench sim clocks each call). Before
        `run()`."""
        self.zc_client.unsubscribe(wire_zc.REPORT_FILTER)
        self.zc_client.subscribe(wire_zc.REPORT_FILTER, wrap(self.zc.on_report))
        self._cycle.cancel()
        self._cycle = self.scheduler.call_every(self.config.cycle_s, wrap(self.zc.cycle), start_s=FIRST_CYCLE_S)

    def silence_zone(self):
        """The zone hears no report and runs no cycle: the world alone, its trains standing (cbtc bench sim's
        reference). Before `run()`."""
        self.zc_client.unsubscribe(wire_zc.REPORT_FILTER)
        self._cycle.cancel()

    def clients(self):
        """Every client of the mock broker in this run: the zone's, the trains', the strays', the recorder's."""
        sniffer = getattr(self.recorder, "_sniffer", None)   # a network's recorder reads truth, not the wire
        return [self.zc_client] + [t.client for t in self.trains + self.strays] + ([sniffer] if sniffer else [])

    def _ranging(self, index):
        """The train-to-train ranging driver of train `index` (None unless the config asks for ranging)."""
        if self.config.ranging is None:
            return None
        from cbtc.ranging.transponder import RangingSensor
        from cbtc.sim.ranging import SimRanging
        sensor = RangingSensor(seed=self.config.seed, **self.config.ranging)
        rng = np.random.default_rng([self.config.seed, index, 7])
        return SimRanging(self.config.layout, self.trains, index, sensor, rng)

    @staticmethod
    def _ticker(train):
        return train.tick

    def record_reports(self, sink) -> None:
        """Hand every report the zone accepts (this one and any that replaces it) to `sink`."""
        self._report_sinks.append(sink)
        self.zc.reports.subscribe(sink)

    def run(self):
        config = self.config
        step_s = 1.0
        t_s = 0.0
        self._report_progress(t_s)
        with run_clock.simulated(self.scheduler.now_s):   # its log lines carry its own time
            while t_s < config.duration_s:
                t_s = min(config.duration_s, t_s + step_s)
                self.scheduler.run_until(t_s)
                if self._report_progress(t_s):
                    break
        progress.report(self, 1.0, 1.0, "done")   # a run that ends early (its laps made) ends its bar at 100 %
        return self.recorder

    def _report_progress(self, t_s) -> bool:
        """Report simulated seconds of the duration, or, for a run to a number of laps, the laps the slowest train
        made; True once every train has made them (the run is done)."""
        laps = self.config.laps
        if laps is None:
            progress.report(self, t_s, self.config.duration_s)
            return False
        made = min((self.recorder.laps(i) for i in range(len(self.trains))), default=laps)
        progress.report(self, min(made, laps), laps, "laps")
        return made >= laps
