"""What the zone knows of one train: its setup (identity, key, physics, stops) and its state (the newest report, the
estimator, the boots, the command held, the plan, the counts), with the per-report values made once from them."""

from dataclasses import dataclass, field

from cbtc.authority.rules import following_reach_m, horizon_m
from cbtc.authority.values import TrainPicture
from cbtc.estimation.estimate import BoardClock
from cbtc.protocol import wire
from cbtc.railway.train_profile import TrainProfile
from cbtc.zone.boots import BootTracker


@dataclass
class TrainSetup:
    """What the controller is told about a train: identity, key, physics, and where it stops."""

    train_id: str
    key: bytes
    profile: TrainProfile = field(default_factory=TrainProfile)
    stops: tuple = ()                   # station names this train stops at
    dwell_s: tuple = (1.0, 3.0)         # dwell time drawn uniformly from this range at each stop
    frame: object = None                # on a track network, the path Layout of its itinerary the zone sees it on
    itinerary: object = None            # ... and that itinerary's Route (None on a single path: the layout's)
    legs: tuple = None                  # ... or the legs it reverses between (cbtc.railway.legs), frame the first's


class TrainState:
    """The controller's picture of one train.

    frame_of_leg: where its sensors read (`sensor_frame`: the frame, or the frame shifted when it runs the other end
    first), which of its legs it runs on a line it reverses on (`leg`), when it turns at the end of one (`turn_at_s`,
    held until then: cbtc.zone.turns), the stops of its plan on its frame (`stops`), and whether the zone has taken
    the way it faces from its board's report yet (`faced`)."""

    def __init__(self, setup: TrainSetup, estimator, rank: int = 0, on_change=None):
        self.setup = setup
        self.train_id = setup.train_id
        self.estimator = estimator
        self.frame = None            # the path Layout the zone sees it on (its itinerary's on a network)
        self.sensor_frame, self.leg, self.turn_at_s, self.stops = None, 0, None, setup.stops   # frame_of_leg above
        self.rank = rank             # its place in the zone's list of trains: ties in position go by it
        self.on_change = on_change   # called with this state when its position may have changed
        self.clock = BoardClock()
        self.report = None           # newest accepted report (dict)
        self.report_recv_s = None
        self.report_t_s = None       # controller time at which the board sampled it
        self.boots = BootTracker()   # which reports move the picture forward; has the board answered us
        self.next_stop = None        # station name or None
        self.leaving = None          # the station whose dwell just ended, until the train is past it
        self.dwell_until_s = None
        self.odo_moved = True        # the newest report's odometer differs from the one before (or it is the first)
        self.still_since_s = None    # controller time of the first report with the odometer it reads now
        self.dwells = 0
        self.limit_s = None          # current authority limit along the track (m), for supervision
        self.safe_m = None           # distance the safety limit allowed at the last command (m)
        self.limited_by = None       # what limited its last command: the authority's reason, or why it is held
        self.eoa_mm = None
        self.travel_dir, self.faced = 0, not setup.legs   # the `dir` commanded: 1 backwards
        self.cmd_seq = 0
        self.command = None          # the newest command sent (a records.Command)
        self.handed = None           # the TrainRecord another zone handed this train over with, until its first report
        self.reports_rejected = 0
        self.last_reject = ""
        self.stop_overruns = 0
        self.restarts = 0
        self.answered_s = None       # controller time of the last command sent to this train
        self.fast_until_s = -1.0     # until then this train is asked for fast reports (a train behind follows it)
        self.fast_need_m = 0.0       # the authority left to that follower (m): the less, the more it needs them
        self.leader_data_t_s = None  # sample time of the train-ahead data the last authority rests on (moving block)
        self.sigma_m = None          # combined 1-sigma of both estimates taken off that authority (k of them)
        self.authority = None        # the newest Authority: what limits this train, and why
        self.mode = None             # its mode (moving block: free, sync, departure)
        self.rng_gap = None          # (controller time s, gap m) last measured by the train's own ranging
        self.gap_alarm = False       # the measured gap disagrees with the estimated one ("picture disagrees")
        self.gap_alarms = 0
        self.deaf_since_s = None     # since when this train's reports have not answered our commands
        self.encoder_failed = False  # its last report named an encoder fault: located afresh once it is healthy
        self.encoder_failures = 0
        self.odometer_jumps = 0      # reports whose odometer moved further than the train can: located afresh
        self.measurements_dropped = 0  # fixes, tags and ranges stamped outside their report
        self.failures = 0            # exceptions in this train's handling: located afresh
        self.failures_said = set()   # the exception types already logged for it
        self.reports_taken = 0       # reports handed to its estimator: its position changes only with these
        self.reach_m = None          # its following reach and horizon (cbtc.authority.rules), set by the zone
        self.horizon_m = None
        self.tail = None             # its tail beacon's TailWatch, from the beacon's first fix (None: none heard)
        self.track_m = None          # the track's length, set by the zone: how far back an unvouched tail may be
        self.swept_from_m = None     # the front-most place of its tail at its previous located report: the track its
        #                              body has certainly passed over since starts there (the zone's SweptTrack)
        self.doubt_span = None       # (low, high) track positions of its head when its encoder failed: handed to each
        #                              estimator started afresh until one is located (UkfEstimator.keep_doubt)
        # what the zone asks of this train per report (its estimate, picture, scale bounds): they change only with a
        # report taken or a new estimator, which empty it, so the train's own command and its follower's share them
        self._memo = {}

    def took_report(self):
        """A report was handed to its estimator: the values kept for the one before are gone."""
        self.reports_taken += 1
        self._memo = {}

    def newest_estimate(self):
        """The estimator's estimate at the newest report's sample time (None while unlocated), made once per report."""
        memo = self._memo
        if "estimate" not in memo:
            memo["estimate"] = self.estimator.estimate(self.report_t_s)
        return memo["estimate"]

    def picture(self):
        """The train as the zone sees it at its newest report (a TrainPicture; its estimate must exist), made once
        per report."""
        memo = self._memo
        picture = memo.get("picture")
        if picture is None:
            est = self.newest_estimate()
            behind_m = est.behind_m   # a tail beacon that finds the train longer than configured reaches further back
            if self.tail is not None and self.tail.confirmed:
                behind_m += self.tail.extra_behind_m(est.s_m, self.report_t_s)
            elif self.setup.profile.tail_beacon:   # a beacon fitted and not heard yet: its tail is not vouched for
                behind_m += self.track_m
            picture = memo["picture"] = TrainPicture(self.train_id, est.s_m, est.sigma_s_m, est.v_mps, self.report_t_s,
                                                     self.setup.profile, est.ahead_m, behind_m)
        return picture

    def odometer_per_m_low(self, k_sigma):
        """The estimator's low bound of the encoder's scale at `k_sigma` (UkfEstimator.odometer_per_m_low), made once
        per report for each `k_sigma`."""
        memo = self._memo
        low = memo.get(k_sigma)
        if low is None:
            low = memo[k_sigma] = self.estimator.odometer_per_m_low(k_sigma)
        return low

    def restart(self, estimator):
        """The board rebooted: forget its clock, odometer frame and position; it must be located again."""
        self.relocate(estimator)
        self.clock = BoardClock()
        self.report = None
        self.tail = None
        self.restarts += 1

    def relocate(self, estimator):
        """Forget where the train is and its odometer's frame: it gets no authority until `estimator` locates it."""
        self.estimator = estimator
        self._memo = {}
        self.swept_from_m = None
        self.eoa_mm = None
        self.limit_s = None
        if self.on_change is not None:
            self.on_change(self)


def train_states(setups, layout, params, estimator_factory, on_change) -> dict:
    """{train id: a TrainState} for each TrainSetup, its fixed distances worked out once; ValueError or LayoutError
    naming a bad id, a train configured twice or a stop the layout does not have."""
    trains = {}
    for setup in setups:
        wire.check_train_id(setup.train_id)
        if setup.train_id in trains:
            raise ValueError(f"zone controller: train id {setup.train_id!r} configured twice")
        frame = setup.frame or layout   # the path the zone sees this train on
        sensors, stops = (setup.legs[0].sensors, setup.legs[0].stops) if setup.legs else (frame, setup.stops)
        for name in stops:
            frame.station(name)  # raises LayoutError naming the known stations
        state = TrainState(setup, estimator_factory(sensors, setup.profile), rank=len(trains),
                           on_change=on_change)
        state.frame, state.sensor_frame, state.stops = frame, sensors, stops
        state.reach_m = following_reach_m(setup.profile)
        state.horizon_m = horizon_m(setup.profile, params)
        state.track_m = frame.length_m
        trains[setup.train_id] = state
    return trains
