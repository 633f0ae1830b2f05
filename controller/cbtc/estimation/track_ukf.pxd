# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class TrackUkf:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, noise, mean, cov, t_s, _spread
    cdef public object _wm0, _wc0, _w, _loop_m, _closed, _gate1
    cdef public object _gate2

