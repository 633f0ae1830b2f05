"""Station stops: the distance to a train's next scheduled stop, and the dwell clock that holds it there.

A train stops at each station of its list in track order; standing within a station's window, it dwells for a time
drawn from its `dwell_s` (the zone's random source, so a seed gives the same run), then leaves for the next. A stop
target is service, not safety: the movement authority never reaches past the end of authority it is given.
"""

import logging

from cbtc.firmware import obu

log = logging.getLogger("cbtc.zone")
NO_MORE_STOPS = ""   # next_stop of a train past the last of its stops on a line
DWELL_FAST_S = 2 * obu.DEFAULTS["report_ms"] / 1000.0   # before a dwell ends, fast reports for this long (s)
STANDING_MMPS = 30   # slower than this, braked or not counting: standing, for the dwell (the board's creep speed)


class StationStops:
    def __init__(self, rng):
        self.rng = rng   # draws each dwell's length (the zone's, seeded)

    def stop_m(self, state, now_s):
        """Distance (m) to the next scheduled stop, or None (no stop to make now); runs the dwell clock."""
        stops = state.stops
        if not stops:
            return None
        est = state.newest_estimate()
        first = state.next_stop is None
        if first:
            state.next_stop = self.next_station(state.frame, est.s_m, stops, at_station_ok=True)
        if state.next_stop == NO_MORE_STOPS:
            return None
        layout = state.frame
        station = layout.station(state.next_stop)
        to_stop_m = self._signed_ahead(layout, est.s_m, station.s_m)
        if first and to_stop_m < -station.window_m:
            state.leaving = station.name   # it starts just past the station: no stop there this time round
        # standing: no speed; or slower than the board's creep speed and braked (no drive: it stops within a loop)
        # or with no count since the report before (the board's speed decays for a while after its last edge;
        # waiting for it to reach 0 only delays the dwell)
        report = state.report
        standing = report["v_mmps"] == 0 or (report["v_mmps"] < STANDING_MMPS and (
            report["duty"] == 0 or not state.odo_moved))
        if state.dwell_until_s is not None:
            if now_s >= state.dwell_until_s:
                state.dwell_until_s = None
                state.dwells += 1
                state.leaving = station.name
                state.next_stop = self.next_station(layout, station.s_m + 0.01, stops)
                return None
            return 0.0   # dwelling: held where it stands (the estimate moving by a mm must not start it again)
        if state.leaving is not None:
            # the station just left may be the next one too (a one-station list): no stop there, and no overrun,
            # until the train is past it (its distance then runs the long way round)
            if state.leaving == station.name and to_stop_m <= station.window_m:
                return None
            state.leaving = None
        if standing and abs(to_stop_m) <= station.window_m:
            # the dwell runs from the first report the odometer read where it stands: the train stood still by then,
            # and the reports since only showed its speed measure decaying
            low, high = state.setup.dwell_s
            state.dwell_until_s = min(now_s, state.still_since_s) + self.rng.uniform(low, high)
            return 0.0
        if to_stop_m < -station.window_m:
            # passed the stop point beyond its window: count it and move on rather than reverse
            state.stop_overruns += 1
            log.warning("train %s overran station %s by %.3f m", state.train_id, station.name, -to_stop_m)
            state.next_stop = self.next_station(layout, station.s_m + 0.01, stops)
            state.leaving = station.name   # counted once: not again until the train has left it behind
            return None
        return to_stop_m

    @staticmethod
    def _signed_ahead(layout, from_s, to_s):
        """Forward distance from `from_s` to `to_s` on `layout`; on a loop, a point up to 1 m behind is negative."""
        ahead = layout.ahead_m(from_s, to_s)
        if layout.closed and ahead > layout.length_m - 1.0:
            ahead -= layout.length_m
        return ahead

    def next_station(self, layout, s_m, stops, at_station_ok=False):
        """The first station in `stops` ahead of `s_m` along the track of `layout` (the train's frame); with
        `at_station_ok`, a station whose stop window holds `s_m` (a train that starts at a platform dwells there
        first); NO_MORE_STOPS on a line past its last stop."""
        def distance(name):
            station = layout.station(name)
            if at_station_ok and abs(self._signed_ahead(layout, s_m, station.s_m)) <= station.window_m:
                return 0.0
            return layout.ahead_m(s_m, station.s_m)
        ahead = [name for name in stops if distance(name) >= 0.0]
        return min(ahead, key=distance) if ahead else NO_MORE_STOPS

    @staticmethod
    def leaving_soon(state, now_s):
        """True in the last two report periods of `state`'s dwell: its reports come fast then, so the dwell ends (at
        the first report on or after its time) within a fast report period, not up to a whole one of the board's."""
        return state.dwell_until_s is not None and state.dwell_until_s - now_s <= DWELL_FAST_S
