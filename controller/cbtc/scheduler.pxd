# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class VirtualScheduler:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _now_s, _queue, _counter, _stopped

cdef class _Periodic:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _scheduler, _period_s, _fn, _k, _start_s, _handle

