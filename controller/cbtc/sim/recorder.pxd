# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); a sample
# reads the virtual trains and their boards as C types

cimport cython

from cbtc.firmware.obu cimport OnboardUnit
from cbtc.sim.virtual_train cimport VirtualTrain

cdef class Recorder:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object sim, keep_reports, keep_samples, layout, _t_s, _samples
    cdef public object _t_first_s, _t_last_s, _moving_last_s, _crossings, _gap, _following
    cdef public object _error, _window, _ever_constrained, _reach_m, collisions, overruns
    cdef public object rolled_onto, _travelled_before, granted_beyond_m, room_m, _colliding, _overrun
    cdef public object _heard, _reports, _index, _sniffer

    @cython.locals(train=VirtualTrain)
    cpdef sample(self, now_s)
    cpdef _gap_to_ahead(self, i, heads, tails, ahead, everyone, moved, first)
    cpdef _estimate_error(self, i, VirtualTrain train, now_s, head_s_m)

    @cython.locals(obu=OnboardUnit)
    cpdef _granted(self, i, VirtualTrain train, now_s, heads, tails, ahead, everyone)
