"""What the policy decides a train's authority from, beyond the two trains' pictures: the trains departing (for
Takagi's departure control) and every train's span as the track circuits see it (for fixed blocks)."""

from operator import attrgetter

_RANK = attrgetter("rank")   # the zone's order of its trains


class Departures:
    def __init__(self):
        self._departing = {}      # train id -> state, trains whose newest authority is a departure
        self._for = {}            # state -> the profiles of the departing trains but it (Situation.departing), kept
        #                           until a train's departure begins or ends

    def of_others(self, state):
        """The profiles of the departing trains but `state`'s, in the zone's order."""
        if not self._departing:
            return ()
        departing = self._for.get(state)
        if departing is None:
            departing = self._for[state] = tuple([
                other.setup.profile for other in sorted(self._departing.values(), key=_RANK) if other is not state])
        return departing

    def took(self, state, mode):
        """`state`'s newest authority is of `mode`."""
        if (mode == "departure") != (state.train_id in self._departing):
            if mode == "departure":
                self._departing[state.train_id] = state
            else:
                del self._departing[state.train_id]
            self._for.clear()


def track_spans(policy, trains, layout, k_sigma):
    """(train_id, head_s, tail_s) of every train as the track circuits see them: the world's own when the policy
    has them (simulation), otherwise the located trains' estimates widened by k sigma."""
    circuits = getattr(policy, "track_circuits", None)
    if circuits is not None:
        return tuple(circuits())
    spans = []
    for st in trains.values():
        if st.report is None or not st.estimator.localized:
            continue
        est = st.newest_estimate()
        widen = k_sigma * est.sigma_s_m
        spans.append((st.train_id, st.frame.wrap(est.s_m + widen + est.ahead_m),
                      st.frame.wrap(est.s_m - st.setup.profile.length_m - widen - st.picture().behind_m)))
    return tuple(spans)


def own_hold(state, blind, unswept):
    """Why `state`'s train gets no authority whatever the other trains do, or None: two boards report under its id,
    an obstacle is seen nowhere (`blind`: its name), its board brakes it for good (motor wired reversed, train line
    open), the network's track is not cleared (`unswept`), or it is being located afresh (it has just reversed)."""
    if not state.estimator.localized:
        return f"held: {state.train_id} not located"
    if state.turn_at_s is not None:
        return "held: about to reverse at the end of its leg"
    if state.boots.twins:
        return f"held: two boards report as {state.train_id}"
    if blind is not None:
        return f"held: {blind}, position unknown"
    faults = () if state.report is None else state.report["flt"]
    if "reverse" in faults:
        return "held: it ran backwards when driven (motor wired reversed?): fix it, then reboot the board"
    if "split" in faults:
        return "held: its train line opened (a car came off?): recouple, then reboot"
    if unswept:
        return "held: the network's track is not cleared (cbtc zone --clear-track all once only the zone's trains " \
               "stand on it)"
    return None


def hold_reason(trains, unanswered):
    """Why every train is held (no authority): the first train not located, or not answering this zone."""
    for st in trains.values():
        if st.report is None:
            return f"held: {st.train_id} not heard"
        if not st.estimator.localized:
            return f"held: {st.train_id} not located"
    if unanswered:
        return f"held: {min(unanswered, key=_RANK).train_id} not answering"
    return "held"
