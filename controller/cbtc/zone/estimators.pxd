# The compiled build's C type for Estimators (setup.py, tests/test_pxd.py): a train's state is a TrainState, so its
# slots are read directly; a report is a dict
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cimport cython

from cbtc.zone.train_state cimport TrainState

cdef class Estimators:
    cdef object __weakref__
    cdef public object layout, params, refusals, factory, facing

    cpdef fresh(self, TrainState state)
    @cython.locals(report=dict, previous=dict)
    cpdef feed(self, TrainState state, report, previous, payload, recv_s)
