# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class MockBroker:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object scheduler, _rng, _clients, _routes, _retained, running
    cdef public object last_error, stats

