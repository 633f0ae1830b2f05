# The compiled build's C types for the zone's indexes (setup.py, tests/test_pxd.py): a train's state is a TrainState,
# so its slots are read directly
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.zone.train_state cimport TrainState

cdef class TrainOrder:
    cdef object __weakref__
    cdef public object closed, moved, _order, _placed, _located

    cpdef index_of(self, TrainState state)
    cpdef leader_of(self, located, i)

cdef class ReportAges:
    cdef object __weakref__
    cdef public object unheard, _heard

    cpdef took(self, TrainState state, recv_s)
    cpdef other_stale(self, TrainState state, now_s, max_age_s)
    cpdef _oldest(self)
