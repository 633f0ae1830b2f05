# The compiled build's C type for CommandWriter (setup.py, tests/test_pxd.py): a train's state is a TrainState, so
# its slots are read directly; a report is a dict
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cimport cython

from cbtc.zone.train_state cimport TrainState

cdef class CommandWriter:
    cdef object __weakref__
    cdef public object layout, params, client, session_id, refusals, ages, commands

    @cython.locals(report=dict)
    cpdef send(self, TrainState state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, rpt_ms, now_s)
    @cython.locals(report=dict)
    cpdef _end_of_authority_mm(self, TrainState state, safe_m, scale_low, dec_mps2, now_s)
