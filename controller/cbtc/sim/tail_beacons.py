"""The IPS modem's view of each train's tail beacon (a second beacon on the last car, `TrainProfile.tail_beacon`):
fixes sampled where that beacon truly is (with a dropped car, on the car), handed to the zone controller at its own
time, as the modem on the controller's machine reports every beacon's fixes."""

import numpy as np

from cbtc.sim.drivers import SimIps


class TailBeacons:
    def __init__(self, sim):
        self.sim = sim
        self._beacons = [(train, SimIps(train.profile, train.layout,
                                        np.random.default_rng([sim.config.seed, index, 13])))
                         for index, train in enumerate(sim.trains) if train.profile.tail_beacon]

    def __bool__(self):
        return bool(self._beacons)

    def tick(self, now_s: float) -> None:
        now_ms = int(round(now_s * 1000))
        for train, ips in self._beacons:
            ips.sample(now_ms, train.beacon_s)
            fix = ips.poll(now_ms)
            if fix is not None:   # stamped at its sample, a latency before it arrives
                self.sim.zc.on_tail_fix(train.train_id, now_s - train.profile.ips_latency_s, fix[1], fix[2])
