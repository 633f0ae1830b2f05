# The compiled build's C type for Departures (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly

from cbtc.zone.train_state cimport TrainState

cdef class Departures:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _departing, _for

    cpdef of_others(self, TrainState state)
    cpdef took(self, TrainState state, mode)
