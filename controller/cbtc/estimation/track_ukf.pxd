# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class TrackUkf:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, noise, mean, cov, t_s, _spread
    cdef public object _wm0, _wc0, _w, _loop_m, _closed, _gate1
    cdef public object _gate2

