# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class BoardClock:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object offset_s, _ref_ms, _ref_unwrapped_ms

