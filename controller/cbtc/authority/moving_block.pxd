# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class MovingBlockPolicy:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object params, sync_tolerance_m, takagi

