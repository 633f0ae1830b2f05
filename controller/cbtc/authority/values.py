"""What a policy is given and what it gives back: frozen values, so an authority is a function of them alone."""

from cbtc.frozen import frozen_value
from cbtc.railway.layout import Layout
from cbtc.railway.train_profile import TrainProfile


@frozen_value
class TrainPicture:
    """One train as the zone sees it: its head estimate at its newest report, and when that report was made."""

    train_id: str
    s_m: float            # head position along the track (m)
    sigma_s_m: float      # its 1-sigma (m)
    v_mps: float
    data_t_s: float       # controller time of the report the estimate rests on (s)
    profile: TrainProfile
    ahead_m: float = 0.0  # beyond sigma, how much further ahead (behind) the train may be while its sensors disagree
    behind_m: float = 0.0  # (m, >= 0): the front-most head is s_m + ahead_m, the rear-most tail less behind_m


@frozen_value
class Situation:
    """Everything a policy may use to decide one train's authority."""

    layout: Layout
    now_s: float
    cycle_s: float                    # the zone's command cycle (s)
    own: TrainPicture
    leader: TrainPicture = None       # the train ahead; None: alone on the track
    measured_gap: tuple = None        # (controller time s, gap m) of the train's own ranging to the leader, or None
    ranging_sigma_m: float = 0.02     # 1-sigma of a measured gap (cbtc.ranging.transponder)
    use_measured_gap: bool = True     # False: a measured gap only raises the alarm
    departing: tuple = ()             # profiles of the other trains whose last authority was a departure, zone order
    spans: tuple = ()                 # (train_id, head_s, tail_s) of every train as the track circuits see them
    received_code: int = None         # the fixed-block speed code the train received (None: the one sent)


@frozen_value
class Authority:
    """How far a train may go and how, and why: `reason` names what limits it (a train, the line's end, a block)."""

    distance_m: float                 # how far the head may still go (m)
    v_cap_mps: float
    acc_mps2: float
    dec_mps2: float
    mode: str                         # moving block: free, sync or departure; fixed block: the speed code's name
    reason: str
    leader_data_t_s: float = None     # report time of the train-ahead data it rests on (moving block)
    sigma_m: float = None             # combined 1-sigma of both estimates taken off it (k_sigma of them)
    gap_est_m: float = None           # the estimated gap to the train ahead (m)
    gap_alarm: bool = None            # the train's own ranging disagrees with that gap; None: no fresh ranging

    def cut_to(self, distance_m: float, reason: str) -> "Authority":
        """This authority with its distance and reason changed, the rest kept (dataclasses.replace's result, made at
        a quarter of its cost: a zone cuts most authorities of free-running trains to their horizon)."""
        return Authority(distance_m, self.v_cap_mps, self.acc_mps2, self.dec_mps2, self.mode, reason,
                         self.leader_data_t_s, self.sigma_m, self.gap_est_m, self.gap_alarm)
