# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class Path:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object segments, closed, start_pose, length_m, end_pose, _starts
    cdef public object _lens, _seg, _seg_ends, _start, _len, _k
    cdef public object _arc, _safe_k, _x0, _y0, _h0, _cx
    cdef public object _cy

