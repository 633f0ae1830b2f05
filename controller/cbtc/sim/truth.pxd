# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class TruthMonitor:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, trains, collisions, _inside, moved_past_eoa_mm, _odo_mm
    cdef public object _sliding

