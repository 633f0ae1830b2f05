# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class Recorder:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object sim, keep_reports, keep_samples, layout, _t_s, _samples
    cdef public object _t_first_s, _t_last_s, _moving_last_s, _crossings, _gap, _following
    cdef public object _error, _window, _ever_constrained, _reach_m, collisions, overruns
    cdef public object rolled_onto, _travelled_before, granted_beyond_m, room_m, _colliding, _overrun
    cdef public object _heard, _reports, _index, _sniffer

