# The compiled build's C type for StationStops (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.zone.train_state cimport TrainState

cdef class StationStops:
    cdef object __weakref__
    cdef public object rng

    cpdef stop_m(self, TrainState state, now_s)
