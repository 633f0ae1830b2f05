# The compiled build's C type for FastReports (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.zone.train_state cimport TrainState

cdef class FastReports:
    cdef object __weakref__
    cdef public object slots, hold_s, _wanting, _lapse_s, _ranked

    cpdef granted(self, TrainState state, now_s)
    cpdef want(self, TrainState state, need_m, now_s)
    cpdef _unrank(self, TrainState state)
