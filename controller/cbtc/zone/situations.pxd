# The compiled build's C type for Departures (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.zone.train_state cimport TrainState

cdef class Departures:
    cdef object __weakref__
    cdef public object _departing, _for

    cpdef of_others(self, TrainState state)
    cpdef took(self, TrainState state, mode)
