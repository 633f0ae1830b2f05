# The compiled build's C type for StationStops (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly

from cbtc.zone.train_state cimport TrainState

cdef class StationStops:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, rng

    cpdef stop_m(self, TrainState state, now_s)
