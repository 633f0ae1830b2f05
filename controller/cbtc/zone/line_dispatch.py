"""The zone's dispatcher on a line trains reverse on: a run to a train's next place to wait is set only when the
railway stays live after it (cbtc.railway.dispatcher), so four trains on two termini and a passing loop never fill
the line facing each other.

Each train's places are the sections its legs can wait on (a station's section, a leg's end), in the order its legs
run them, round and round: its plan for the dispatcher, one place per stop. The dispatcher's picture of the railway
is where each train stands or is bound (the place of the run last set for it) and how far round its places it is;
it is read from the trains once they are all located, and then kept as runs are set.
"""

from cbtc.railway.dispatcher import Dispatcher


def places(legs, waits):
    """[(leg index, step index, section)] of the places a train on `legs` can wait at, in the order it runs them: on
    each leg, every step after its first (where the train turned) on a section of `waits`, and the leg's end."""
    out = []
    for k, leg in enumerate(legs):
        steps = leg.route.steps
        out.extend((k, i, name) for i, (name, _fwd) in enumerate(steps)
                   if i and (name in waits or i == len(steps) - 1))
    return out


class LineDispatch:
    def __init__(self, graph, legs_of, waits):
        """`legs_of`: train -> its legs; `waits`: the sections a train may wait on."""
        self.places = {t: places(legs, waits) for t, legs in legs_of.items()}
        sections = {name for found in self.places.values() for _k, _i, name in found}
        sections |= {name for legs in legs_of.values() for leg in legs for name, _f in leg.route.steps}
        self.dispatcher = Dispatcher(graph, {name: (name, 0.0) for name in sections},
                                     {t: [(name,) for _k, _i, name in found] for t, found in self.places.items()})
        self.at = None      # train -> the place it stands at or is bound to; None until every train is located
        self.index = {}     # train -> the index of its next place
        self.within = set()  # trains read at start on a place's step: a run within it is theirs until they leave

    def start(self, where):
        """Read the picture from `where`: train -> (its leg index, the step its head is on, that step's section)."""
        self.at, self.index, self.within = {}, {}, set()
        for train, (leg, step, section) in where.items():
            found = self.places[train]
            self.at[train] = section
            if (leg, step, section) in found:
                self.within.add(train)
            self.index[train] = next((n for n, (k, i, _s) in enumerate(found) if (k, i) > (leg, step)), 0)

    def refusal(self, train, place):
        """Why a run of `train` to `place` may not be set now ("" when it may)."""
        if self.at is None:
            return "the dispatcher has not yet seen every train located"
        if train in self.within and place == self.at[train]:
            return ""   # it stands in the place it counts as at, short of its stop (a zone restarted under it)
        _k, _i, due = self.places[train][self.index[train]]
        if place != due:
            return f"its next place is {due}, not {place}"
        if place not in {move.station for move in self.dispatcher.moves(train, self.at, self.index, True)}:
            return f"a run to {place} now could end with trains facing each other: the dispatcher holds it"
        return ""

    def moved(self, train, place):
        """A run of `train` to `place` was set: it counts as there (already, for a run within that place)."""
        if train in self.within:
            self.within.discard(train)
            if place == self.at[train]:
                return
        self.at[train] = place
        self.index[train] = (self.index[train] + 1) % len(self.places[train])

