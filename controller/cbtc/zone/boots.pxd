# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class BootTracker:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object boot, last_seq, last_recv_s, answered, left, _leaving
    cdef public object _leaving_seq, twins, _baselines

