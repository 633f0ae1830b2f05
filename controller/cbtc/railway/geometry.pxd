# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class Path:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object segments, closed, start_pose, length_m, end_pose, _starts
    cdef public object _lens, _seg, _seg_ends, _start, _len, _k
    cdef public object _arc, _safe_k, _x0, _y0, _h0, _cx
    cdef public object _cy

